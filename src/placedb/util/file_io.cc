#include "placedb/util/file_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <cerrno>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace placedb {
namespace fs = std::filesystem;

std::string ReadFileToString(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) PLACEDB_THROW_RUNTIME("cannot open ", path, ": ", std::strerror(errno));
  std::ostringstream out;
  out << in.rdbuf();
  if (in.bad()) PLACEDB_THROW_RUNTIME("error reading ", path);
  return out.str();
}

namespace {

void WriteAllOrThrow(int fd, const std::string& data, const std::string& path) {
  size_t written = 0;
  while (written < data.size()) {
    const ssize_t n = ::write(fd, data.data() + written, data.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd);
      PLACEDB_THROW_RUNTIME("cannot write ", path, ": ", std::strerror(err));
    }
    written += static_cast<size_t>(n);
  }
}

}  // namespace

void SyncDirectory(const std::string& dir) {
  const int fd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd < 0) PLACEDB_THROW_RUNTIME("cannot open directory ", dir, ": ", std::strerror(errno));
  ::fsync(fd);
  ::close(fd);
}

void WriteFileAtomic(const std::string& path, const std::string& data) {
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) PLACEDB_THROW_RUNTIME("cannot create ", tmp, ": ", std::strerror(errno));
  WriteAllOrThrow(fd, data, tmp);
  if (::fsync(fd) != 0) {
    const int err = errno;
    ::close(fd);
    PLACEDB_THROW_RUNTIME("cannot fsync ", tmp, ": ", std::strerror(err));
  }
  ::close(fd);
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    PLACEDB_THROW_RUNTIME("cannot rename ", tmp, " to ", path, ": ", std::strerror(err));
  }
  SyncDirectory(fs::path(path).parent_path().string());
}

uint32_t Crc32(const void* data, size_t size, uint32_t crc) {
  const auto* bytes = static_cast<const Bytef*>(data);
  uLong value = crc;
  // zlib takes uInt lengths: feed large buffers in chunks.
  while (size > 0) {
    const uInt chunk = static_cast<uInt>(std::min<size_t>(size, 1u << 30));
    value = crc32(value, bytes, chunk);
    bytes += chunk;
    size -= chunk;
  }
  return static_cast<uint32_t>(value);
}

uint64_t FileSize(const std::string& path) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  return ec ? 0 : static_cast<uint64_t>(size);
}

uint64_t DirectorySize(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return 0;
  uint64_t total = 0;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.is_regular_file()) total += entry.file_size();
  }
  return total;
}

bool HostIsLittleEndian() {
  const uint16_t probe = 1;
  uint8_t first;
  std::memcpy(&first, &probe, 1);
  return first == 1;
}

}  // namespace placedb
