#include "placedb/util/file_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "placedb/util/mapped_file.h"

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

AtomicFileWriter::AtomicFileWriter(std::string path)
    : path_(std::move(path)), tmp_(path_ + ".tmp." + std::to_string(::getpid())) {
  fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) PLACEDB_THROW_RUNTIME("cannot create ", tmp_, ": ", std::strerror(errno));
}

AtomicFileWriter::~AtomicFileWriter() {
  if (fd_ >= 0) ::close(fd_);
  if (!committed_) ::unlink(tmp_.c_str());
}

void AtomicFileWriter::Flush() {
  if (buffer_.empty()) return;
  size_t written = 0;
  while (written < buffer_.size()) {
    const ssize_t n = ::write(fd_, buffer_.data() + written, buffer_.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      PLACEDB_THROW_RUNTIME("cannot write ", tmp_, ": ", std::strerror(errno));
    }
    written += static_cast<size_t>(n);
  }
  buffer_.clear();
}

void AtomicFileWriter::Write(const void* data, size_t size) {
  PLACEDB_CHECK(!committed_, "write after commit");
  constexpr size_t kBuffer = 1 << 20;
  if (buffer_.size() + size > kBuffer) Flush();
  if (size >= kBuffer) {
    buffer_.assign(static_cast<const char*>(data), size);
    Flush();
  } else {
    buffer_.append(static_cast<const char*>(data), size);
  }
  position_ += size;
}

void AtomicFileWriter::Align(size_t alignment) {
  static const char kZeros[64] = {};
  while (position_ % alignment != 0) {
    Write(kZeros, std::min<size_t>(sizeof(kZeros), alignment - position_ % alignment));
  }
}

void AtomicFileWriter::WriteAt(uint64_t offset, const void* data, size_t size) {
  PLACEDB_CHECK(offset + size <= position_, "WriteAt beyond what was written");
  Flush();
  size_t done = 0;
  while (done < size) {
    const ssize_t n = ::pwrite(fd_, static_cast<const char*>(data) + done, size - done,
                               static_cast<off_t>(offset + done));
    if (n < 0) {
      if (errno == EINTR) continue;
      PLACEDB_THROW_RUNTIME("cannot write ", tmp_, ": ", std::strerror(errno));
    }
    done += static_cast<size_t>(n);
  }
}

void AtomicFileWriter::Commit() {
  Flush();
  if (::fsync(fd_) != 0) PLACEDB_THROW_RUNTIME("cannot fsync ", tmp_, ": ", std::strerror(errno));
  ::close(fd_);
  fd_ = -1;
  if (::rename(tmp_.c_str(), path_.c_str()) != 0) {
    PLACEDB_THROW_RUNTIME("cannot rename ", tmp_, " to ", path_, ": ", std::strerror(errno));
  }
  committed_ = true;
  SyncDirectory(fs::path(path_).parent_path().string());
}

DirectoryHandle::DirectoryHandle(const std::string& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd_ < 0) PLACEDB_THROW_RUNTIME("cannot open directory ", path, ": ", std::strerror(errno));
}

DirectoryHandle::~DirectoryHandle() {
  if (fd_ >= 0) ::close(fd_);
}

bool DirectoryHandle::ReadFile(const std::string& name, std::string* out, size_t max_bytes) const {
  const std::string shown = (fs::path(path_) / name).string();
  const int fd = ::openat(fd_, name.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) return false;
    PLACEDB_THROW_RUNTIME("cannot open ", shown, ": ", std::strerror(errno));
  }
  out->clear();
  char buf[65536];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof(buf));
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd);
      PLACEDB_THROW_RUNTIME("cannot read ", shown, ": ", std::strerror(err));
    }
    if (n == 0) break;
    if (out->size() + static_cast<size_t>(n) > max_bytes) {
      ::close(fd);
      PLACEDB_THROW_RUNTIME(shown, " is larger than ", max_bytes, " bytes");
    }
    out->append(buf, static_cast<size_t>(n));
  }
  ::close(fd);
  return true;
}

std::shared_ptr<const MappedFile> DirectoryHandle::MapFile(const std::string& name) const {
  const std::string shown = (fs::path(path_) / name).string();
  const int fd = ::openat(fd_, name.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) return nullptr;
    PLACEDB_THROW_RUNTIME("cannot open ", shown, ": ", std::strerror(errno));
  }
  try {
    auto file = MappedFile::FromFd(fd, shown);
    ::close(fd);
    return file;
  } catch (...) {
    ::close(fd);
    throw;
  }
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
