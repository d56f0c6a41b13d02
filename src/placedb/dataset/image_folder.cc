#include "placedb/dataset/image_folder.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <filesystem>
#include <system_error>

#include "placedb/dataset/text_lines.h"
#include "placedb/util/check.h"
#include "placedb/util/file_io.h"

namespace placedb {
namespace {

namespace fs = std::filesystem;

bool HasImageExtension(const fs::path& file) {
  static const std::array<std::string, 9> kExtensions = {".jpg", ".jpeg", ".png",  ".bmp", ".ppm",
                                                         ".pgm", ".tif",  ".tiff", ".webp"};
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return std::find(kExtensions.begin(), kExtensions.end(), ext) != kExtensions.end();
}

// Checks the range against the `count` listed images and returns the
// 0-based [begin, end) it selects.
std::pair<size_t, size_t> SelectRange(size_t count, int first, int last,
                                      const std::string& source) {
  if (first < 1) PLACEDB_THROW_INVALID(source, ": `first` must be >= 1 (1-based; got ", first, ")");
  if (last < 0) {
    PLACEDB_THROW_INVALID(source, ": `last` must be >= 0 (0: to the end; got ", last, ")");
  }
  if (last != 0 && first > last) {
    PLACEDB_THROW_INVALID(source, ": `first` (", first, ") is after `last` (", last, ")");
  }
  if (static_cast<size_t>(first) > count) {
    PLACEDB_THROW_INVALID(source, ": `first` (", first, ") is beyond the ", count,
                          " images listed");
  }
  size_t end = last == 0 ? count : static_cast<size_t>(last);
  if (end > count) {
    spdlog::warn("{}: last = {} is beyond the {} images listed; using {}", source, last, count,
                 count);
    end = count;
  }
  return {static_cast<size_t>(first - 1), end};
}

// Numbers `paths` 1..n and keeps the selected range.
std::vector<Frame> MakeFrames(const std::vector<std::string>& paths, int first, int last,
                              const std::string& source) {
  if (paths.empty()) PLACEDB_THROW_INVALID(source, ": no images found");
  const auto [begin, end] = SelectRange(paths.size(), first, last, source);
  std::vector<Frame> frames;
  frames.reserve(end - begin);
  for (size_t i = begin; i < end; ++i) {
    Frame frame;
    frame.id = static_cast<int>(i + 1);
    frame.image_path = paths[i];
    frames.push_back(std::move(frame));
  }
  return frames;
}

}  // namespace

std::vector<Frame> ListImageFolder(const std::string& dir, int first, int last) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) PLACEDB_THROW_NOT_FOUND("image folder not found: ", dir);
  std::vector<std::string> names;
  fs::directory_iterator it(dir, ec);
  if (ec) PLACEDB_THROW_READ_ERROR(ec.value(), "cannot list image folder ", dir);
  for (const fs::directory_entry& entry : it) {
    const fs::path& file = entry.path();
    const std::string name = file.filename().string();
    if (name.empty() || name[0] == '.' || !HasImageExtension(file)) continue;
    std::error_code type_ec;
    if (!entry.is_regular_file(type_ec)) continue;
    names.push_back(name);
  }
  if (names.empty() && (fs::is_regular_file(fs::path(dir) / "rgb.txt", ec) ||
                        fs::is_directory(fs::path(dir) / "rgb", ec))) {
    PLACEDB_THROW_INVALID(dir, ": no images found; it looks like a TUM RGB-D folder (rgb.txt, "
                               "rgb/): read it with `tum`");
  }
  std::sort(names.begin(), names.end());
  std::vector<std::string> paths;
  paths.reserve(names.size());
  for (const std::string& name : names) paths.push_back((fs::path(dir) / name).string());
  return MakeFrames(paths, first, last, dir);
}

std::vector<Frame> ReadImageList(const std::string& list_file, int first, int last) {
  const std::vector<internal::TextLine> lines = internal::ReadDataLines(list_file, "image list");
  const fs::path base = fs::path(list_file).parent_path();
  std::vector<std::string> paths;
  paths.reserve(lines.size());
  for (const internal::TextLine& line : lines) {
    const std::string path = (base / line.text).string();  // an absolute entry stays as is
    if (!internal::IsRegularFile(path)) {
      // Kept, so ids stay positions in the list; the build skips and counts it.
      spdlog::warn("{}:{}: image not found: {}", list_file, line.number, path);
    }
    paths.push_back(path);
  }
  return MakeFrames(paths, first, last, list_file);
}

std::vector<Frame> ReadImages(const std::string& path, int first, int last) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) return ListImageFolder(path, first, last);
  if (fs::is_regular_file(path, ec)) return ReadImageList(path, first, last);
  if (!fs::exists(path, ec)) {
    PLACEDB_THROW_NOT_FOUND(path, " does not exist (`images` takes an image folder or a file "
                                  "listing images)");
  }
  PLACEDB_THROW_INVALID(path, " is neither a folder nor a regular file (`images` takes an image "
                              "folder or a file listing images)");
}

}  // namespace placedb
