#include "placedb/storage/folder.h"

#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <unordered_set>

#include "placedb/storage/database.h"
#include "placedb/util/check.h"

namespace placedb {
namespace fs = std::filesystem;

std::string StoredImageFileName(int32_t id) {
  char name[32];
  std::snprintf(name, sizeof(name), "%s/%06d.png", kStoredImageFolder, id);
  return name;
}

bool IsPlacedbStoredImageName(const std::string& name) {
  constexpr size_t kSuffix = 4;  // ".png"
  if (name.size() < 6 + kSuffix || name.size() > 10 + kSuffix) return false;
  if (name.compare(name.size() - kSuffix, kSuffix, ".png") != 0) return false;
  return std::all_of(name.begin(), name.end() - kSuffix,
                     [](char c) { return c >= '0' && c <= '9'; });
}

size_t SweepDatabaseDebris(const std::string& dir, const Database& current,
                           const std::function<bool(const std::string&)>& stale_index) {
  size_t swept = 0;
  try {
    const DirectoryHandle folder(dir);
    swept += SweepTempFiles(folder);
    for (const std::string& name : folder.List()) {
      const bool stale_keyframes =
          (Database::IsKeyframesFileName(name) && name != current.keyframes_file()) ||
          name == "keyframes.writing.bin";
      if ((stale_keyframes || stale_index(name)) && folder.RemoveRegularFile(name)) ++swept;
    }
    if (const auto images = DirectoryHandle::OpenChild(folder, kStoredImageFolder)) {
      swept += SweepTempFiles(*images);
      std::unordered_set<std::string> named;
      named.reserve(current.size());
      for (const Keyframe& k : current.keyframes()) {
        if (!k.image_file.empty()) named.insert(fs::path(k.image_file).filename().string());
      }
      for (const std::string& name : images->List()) {
        if (IsPlacedbStoredImageName(name) && named.count(name) == 0 &&
            images->RemoveRegularFile(name)) {
          ++swept;
        }
      }
    }
  } catch (const Error& e) {
    spdlog::debug("{}: sweeping stopped: {}", dir, e.what());
  }
  swept += RemoveAbandonedBuilds(dir, false);
  if (swept > 0)
    spdlog::info("{}: removed {} files left by writers that did not finish", dir, swept);
  return swept;
}

size_t RemoveAbandonedBuilds(const std::string& dir, bool include_own) {
  fs::path path = fs::path(dir).lexically_normal();
  if (!path.has_filename()) path = path.parent_path();
  const fs::path parent = path.has_parent_path() ? path.parent_path() : fs::path(".");
  const std::string prefix = path.filename().string() + ".building.";
  size_t removed = 0;
  std::error_code ec;
  for (fs::directory_iterator it(parent, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string pid_text = name.substr(prefix.size());
    if (pid_text.empty() || pid_text.size() > 9 ||
        !std::all_of(pid_text.begin(), pid_text.end(), ::isdigit)) {
      continue;
    }
    std::error_code status_ec;
    if (!fs::is_directory(it->symlink_status(status_ec)) || status_ec) continue;  // no links
    const long pid = std::stol(pid_text);
    if ((include_own && pid == ::getpid()) || (pid != ::getpid() && ProcessIsGone(pid))) {
      spdlog::info("removing {}, left by a build that did not finish", it->path().string());
      std::error_code remove_ec;
      fs::remove_all(it->path(), remove_ec);
      if (!remove_ec) ++removed;
    }
  }
  return removed;
}

std::unique_ptr<DirectoryHandle> StoredImageFolderForWriting(const std::string& dir) {
  const fs::path images = fs::path(dir) / kStoredImageFolder;
  const DirectoryHandle folder(dir);
  if (auto handle = DirectoryHandle::OpenChild(folder, kStoredImageFolder)) return handle;
  struct stat st;
  if (::lstat(images.c_str(), &st) == 0) {
    PLACEDB_THROW_INVALID(
        images.string(), S_ISLNK(st.st_mode) ? " is a symlink" : " is not a directory",
        ": placedb stores keyframe images only in a real folder of the database (replace it with "
        "a folder holding the stored images, or rebuild the database)");
  }
  if (::mkdir(images.c_str(), 0755) != 0 && errno != EEXIST) {
    PLACEDB_THROW_IO("cannot create ", images.string(), ": ", std::strerror(errno));
  }
  auto handle = DirectoryHandle::OpenChild(folder, kStoredImageFolder);
  if (!handle) PLACEDB_THROW_IO("cannot open ", images.string(), " as a folder");
  return handle;
}

}  // namespace placedb
