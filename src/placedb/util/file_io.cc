#include "placedb/util/file_io.h"

#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include "placedb/util/mapped_file.h"

namespace placedb {
namespace fs = std::filesystem;

namespace internal {

void ThrowReadError(int err, const std::string& message, std::string where) {
  const std::string text = message + ": " + std::strerror(err);
  if (err == ENOENT || err == ENOTDIR) throw NotFound(text, std::move(where));
  throw IoError(text, std::move(where));
}

}  // namespace internal

std::string ReadFileToString(const std::string& path) {
  // POSIX calls rather than a stream: their errno tells a missing file
  // (NotFound) from an unreadable one (IoError).
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) PLACEDB_THROW_READ_ERROR(errno, "cannot open ", path);
  std::string out;
  char buf[65536];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof(buf));
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd);
      if (err == EISDIR) PLACEDB_THROW_INVALID(path, " is a directory, not a file");
      PLACEDB_THROW_IO("cannot read ", path, ": ", std::strerror(err));
    }
    if (n == 0) break;
    out.append(buf, static_cast<size_t>(n));
  }
  ::close(fd);
  return out;
}

bool WriteAll(int fd, const char* data, size_t size) {
  size_t written = 0;
  while (written < size) {
    const ssize_t n = ::write(fd, data + written, size - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    written += static_cast<size_t>(n);
  }
  return true;
}

namespace {

// What is at `path` now: nothing (a new path), a regular file, a directory,
// or something a crash-safe replace must not touch (a symlink, a device, a
// FIFO, a socket).
enum class PathKind { kNew, kRegular, kDirectory, kSpecial };

PathKind KindOfPath(const std::string& path) {
  struct stat st;
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return PathKind::kNew;
    PLACEDB_THROW_IO("cannot write ", path, ": ", std::strerror(errno));
  }
  if (S_ISREG(st.st_mode)) return PathKind::kRegular;
  if (S_ISDIR(st.st_mode)) return PathKind::kDirectory;
  return PathKind::kSpecial;
}

// Writes `data` into what `path` names (a symlink's target, a device, a
// FIFO) as a stream: the path itself is left as it is.
void WriteStream(const std::string& path, const std::string& data) {
  int flags = O_WRONLY | O_CLOEXEC;
  struct stat target;
  // A symlink to a regular file is overwritten through the link.
  if (::stat(path.c_str(), &target) == 0 && S_ISREG(target.st_mode)) flags |= O_TRUNC;
  const int fd = ::open(path.c_str(), flags);
  if (fd < 0) PLACEDB_THROW_IO("cannot write ", path, ": ", std::strerror(errno));
  if (!WriteAll(fd, data.data(), data.size())) {
    const int err = errno;
    ::close(fd);
    PLACEDB_THROW_IO("cannot write ", path, ": ", std::strerror(err));
  }
  if (::close(fd) != 0 && errno != EINTR) {
    PLACEDB_THROW_IO("cannot write ", path, ": ", std::strerror(errno));
  }
}

std::atomic<uint64_t> temp_counter{0};

}  // namespace

void SyncDirectory(const std::string& dir) {
  const int fd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd < 0) PLACEDB_THROW_IO("cannot open directory ", dir, ": ", std::strerror(errno));
  ::fsync(fd);
  ::close(fd);
}

std::string TempPathFor(const std::string& path) {
  return path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(++temp_counter);
}

bool IsTempFileName(const std::string& name, long* pid) {
  // "<stem>.tmp.<pid>" or "<stem>.tmp.<pid>.<n>", stem not empty.
  const size_t at = name.rfind(".tmp.");
  if (at == std::string::npos || at == 0) return false;
  auto digits = [](const std::string& text) {
    return !text.empty() && text.size() <= 18 &&
           std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; });
  };
  const std::string rest = name.substr(at + 5);
  const size_t dot = rest.find('.');
  const std::string pid_text = rest.substr(0, dot);
  if (!digits(pid_text)) return false;
  if (dot != std::string::npos && !digits(rest.substr(dot + 1))) return false;
  if (pid != nullptr) *pid = std::stol(pid_text);
  return true;
}

bool ProcessIsGone(long pid) {
  if (pid <= 0 || pid > INT32_MAX) return true;
  return ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH;
}

bool RemoveRegularFile(const std::string& path) {
  struct stat st;
  if (::lstat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return false;
  return ::unlink(path.c_str()) == 0;
}

size_t SweepTempFiles(const DirectoryHandle& dir) {
  size_t removed = 0;
  for (const std::string& name : dir.List()) {
    long pid = 0;
    if (IsTempFileName(name, &pid) && ProcessIsGone(pid) && dir.RemoveRegularFile(name)) ++removed;
  }
  return removed;
}

void WriteFileAtomic(const std::string& path, const std::string& data) {
  switch (KindOfPath(path)) {
    case PathKind::kSpecial:
      WriteStream(path, data);
      return;
    case PathKind::kDirectory:
      PLACEDB_THROW_INVALID("cannot write ", path, ": it is a directory");
    case PathKind::kNew:
    case PathKind::kRegular:
      break;
  }
  const std::string tmp = TempPathFor(path);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) PLACEDB_THROW_IO("cannot create ", tmp, ": ", std::strerror(errno));
  auto fail = [&](const char* what) {
    const int err = errno;
    ::close(fd);
    ::unlink(tmp.c_str());
    PLACEDB_THROW_IO("cannot ", what, " ", tmp, ": ", std::strerror(err));
  };
  if (!WriteAll(fd, data.data(), data.size())) fail("write");
  if (::fsync(fd) != 0) fail("fsync");
  if (::close(fd) != 0 && errno != EINTR) {
    const int err = errno;
    ::unlink(tmp.c_str());
    PLACEDB_THROW_IO("cannot write ", tmp, ": ", std::strerror(err));
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp.c_str());
    PLACEDB_THROW_IO("cannot rename ", tmp, " to ", path, ": ", std::strerror(err));
  }
  SyncDirectory(fs::path(path).parent_path().string());
}

AtomicFileWriter::AtomicFileWriter(std::string path) : path_(std::move(path)) {
  const PathKind kind = KindOfPath(path_);
  if (kind == PathKind::kDirectory || kind == PathKind::kSpecial) {
    PLACEDB_THROW_INVALID("cannot write ", path_, ": not a regular file (write to a file path)");
  }
  tmp_ = TempPathFor(path_);
  fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd_ < 0) PLACEDB_THROW_IO("cannot create ", tmp_, ": ", std::strerror(errno));
}

AtomicFileWriter::~AtomicFileWriter() {
  if (fd_ >= 0) ::close(fd_);
  if (!committed_ && !tmp_.empty()) ::unlink(tmp_.c_str());
}

void AtomicFileWriter::Flush() {
  if (buffer_.empty()) return;
  size_t written = 0;
  while (written < buffer_.size()) {
    const ssize_t n = ::write(fd_, buffer_.data() + written, buffer_.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      PLACEDB_THROW_IO("cannot write ", tmp_, ": ", std::strerror(errno));
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
      PLACEDB_THROW_IO("cannot write ", tmp_, ": ", std::strerror(errno));
    }
    done += static_cast<size_t>(n);
  }
}

void AtomicFileWriter::CommitAs(const std::string& path) {
  const PathKind kind = KindOfPath(path);
  if (kind == PathKind::kDirectory || kind == PathKind::kSpecial) {
    PLACEDB_THROW_INVALID("cannot write ", path, ": not a regular file");
  }
  path_ = path;
  Commit();
}

void AtomicFileWriter::Commit() {
  Flush();
  if (::fsync(fd_) != 0) PLACEDB_THROW_IO("cannot fsync ", tmp_, ": ", std::strerror(errno));
  ::close(fd_);
  fd_ = -1;
  if (::rename(tmp_.c_str(), path_.c_str()) != 0) {
    PLACEDB_THROW_IO("cannot rename ", tmp_, " to ", path_, ": ", std::strerror(errno));
  }
  committed_ = true;
  SyncDirectory(fs::path(path_).parent_path().string());
}

DirectoryHandle::DirectoryHandle(const std::string& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd_ < 0) PLACEDB_THROW_READ_ERROR(errno, "cannot open directory ", path);
}

DirectoryHandle::~DirectoryHandle() {
  if (fd_ >= 0) ::close(fd_);
}

std::unique_ptr<DirectoryHandle> DirectoryHandle::OpenChild(const DirectoryHandle& parent,
                                                            const std::string& name) {
  const std::string shown = (fs::path(parent.path_) / name).string();
  const int fd =
      ::openat(parent.fd_, name.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
  if (fd < 0) {
    // ELOOP: a symlink; ENOTDIR: something else.
    if (errno == ENOENT || errno == ELOOP || errno == ENOTDIR) return nullptr;
    PLACEDB_THROW_IO("cannot open directory ", shown, ": ", std::strerror(errno));
  }
  return std::unique_ptr<DirectoryHandle>(new DirectoryHandle(shown, fd));
}

std::vector<std::string> DirectoryHandle::List() const {
  // fdopendir takes the descriptor over: give it a copy of ours, rewound.
  const int fd = ::openat(fd_, ".", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) PLACEDB_THROW_IO("cannot list ", path_, ": ", std::strerror(errno));
  DIR* d = ::fdopendir(fd);
  if (d == nullptr) {
    const int err = errno;
    ::close(fd);
    PLACEDB_THROW_IO("cannot list ", path_, ": ", std::strerror(err));
  }
  std::vector<std::string> names;
  while (const struct dirent* e = ::readdir(d)) {
    const std::string name = e->d_name;
    if (name != "." && name != "..") names.push_back(name);
  }
  ::closedir(d);
  return names;
}

void DirectoryHandle::WriteFileAtomic(const std::string& name, const std::string& data) const {
  PLACEDB_CHECK(!name.empty() && name.find('/') == std::string::npos,
                "WriteFileAtomic takes a name inside the directory");
  const std::string shown = (fs::path(path_) / name).string();
  const std::string tmp = TempPathFor(name);
  const int fd = ::openat(fd_, tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) PLACEDB_THROW_IO("cannot create a file in ", path_, ": ", std::strerror(errno));
  auto fail = [&](const char* what, int err, bool open) {
    if (open) ::close(fd);
    ::unlinkat(fd_, tmp.c_str(), 0);
    PLACEDB_THROW_IO("cannot ", what, " ", shown, ": ", std::strerror(err));
  };
  if (!WriteAll(fd, data.data(), data.size())) fail("write", errno, true);
  if (::fsync(fd) != 0) fail("fsync", errno, true);
  if (::close(fd) != 0 && errno != EINTR) fail("write", errno, false);
  if (::renameat(fd_, tmp.c_str(), fd_, name.c_str()) != 0) fail("write", errno, false);
  ::fsync(fd_);
}

bool DirectoryHandle::RemoveRegularFile(const std::string& name) const {
  if (name.empty() || name.find('/') != std::string::npos) return false;
  struct stat st;
  if (::fstatat(fd_, name.c_str(), &st, AT_SYMLINK_NOFOLLOW) != 0 || !S_ISREG(st.st_mode))
    return false;
  return ::unlinkat(fd_, name.c_str(), 0) == 0;
}

bool DirectoryHandle::ReadFile(const std::string& name, std::string* out, size_t max_bytes) const {
  const std::string shown = (fs::path(path_) / name).string();
  const int fd = ::openat(fd_, name.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) return false;
    PLACEDB_THROW_IO("cannot open ", shown, ": ", std::strerror(errno));
  }
  out->clear();
  char buf[65536];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof(buf));
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd);
      PLACEDB_THROW_IO("cannot read ", shown, ": ", std::strerror(err));
    }
    if (n == 0) break;
    if (out->size() + static_cast<size_t>(n) > max_bytes) {
      ::close(fd);
      PLACEDB_THROW_CORRUPT(shown, " is larger than ", max_bytes,
                            " bytes, the most placedb reads of it (a damaged or foreign file)");
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
    PLACEDB_THROW_IO("cannot open ", shown, ": ", std::strerror(errno));
  }
  try {
    struct stat st;
    if (::fstat(fd, &st) != 0) PLACEDB_THROW_IO("cannot stat ", shown, ": ", std::strerror(errno));
    // The manifest names this file: anything but a regular file there is a
    // damaged database, not a wrong argument.
    if (!S_ISREG(st.st_mode)) PLACEDB_THROW_CORRUPT(shown, " is not a regular file");
    auto file = MappedFile::FromFd(fd, shown);
    ::close(fd);
    return file;
  } catch (...) {
    ::close(fd);
    throw;
  }
}

std::unique_ptr<DirectoryLock> DirectoryLock::TryLock(const std::string& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) PLACEDB_THROW_READ_ERROR(errno, "cannot open directory ", dir);
  int rc;
  do {
    rc = ::flock(fd, LOCK_EX | LOCK_NB);
  } while (rc != 0 && errno == EINTR);
  if (rc != 0) {
    const int err = errno;
    ::close(fd);
    if (err == EWOULDBLOCK) return nullptr;
    PLACEDB_THROW_IO("cannot lock directory ", dir, ": ", std::strerror(err));
  }
  return std::unique_ptr<DirectoryLock>(new DirectoryLock(fd));
}

DirectoryLock::~DirectoryLock() {
  if (fd_ >= 0) ::close(fd_);
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

bool IsPlainFileName(const std::string& name) {
  if (name.empty() || name.size() > 255 || name[0] == '.') return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
           c == '_' || c == '-';
  });
}

namespace {
// Length of the well-formed UTF-8 sequence at text[i] (1 to 4), 0 when the
// byte there starts none.
size_t Utf8SequenceLength(const std::string& text, size_t i) {
  const auto byte = [&](size_t k) { return static_cast<unsigned char>(text[k]); };
  const unsigned char c = byte(i);
  if (c < 0x80) return 1;
  size_t n = 0;
  unsigned char lo = 0x80, hi = 0xBF;  // the allowed range of the second byte
  if (c >= 0xC2 && c <= 0xDF) {
    n = 2;
  } else if (c >= 0xE0 && c <= 0xEF) {
    n = 3;
    if (c == 0xE0) lo = 0xA0;  // no overlong forms
    if (c == 0xED) hi = 0x9F;  // no surrogates
  } else if (c >= 0xF0 && c <= 0xF4) {
    n = 4;
    if (c == 0xF0) lo = 0x90;  // no overlong forms
    if (c == 0xF4) hi = 0x8F;  // nothing above U+10FFFF
  } else {
    return 0;
  }
  if (text.size() - i < n) return 0;
  if (byte(i + 1) < lo || byte(i + 1) > hi) return 0;
  for (size_t k = 2; k < n; ++k) {
    if (byte(i + k) < 0x80 || byte(i + k) > 0xBF) return 0;
  }
  return n;
}
}  // namespace

bool IsValidUtf8(const std::string& text) {
  for (size_t i = 0; i < text.size();) {
    const size_t n = Utf8SequenceLength(text, i);
    if (n == 0) return false;
    i += n;
  }
  return true;
}

std::string EscapeForTerminal(const std::string& text) {
  static const char kHex[] = "0123456789abcdef";
  std::string out;
  out.reserve(text.size());
  for (size_t i = 0; i < text.size();) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    size_t n = Utf8SequenceLength(text, i);
    // C0 controls and DEL; C1 controls (U+0080..U+009F, 0xC2 0x80..0x9F).
    const bool control = c < 0x20 || c == 0x7F ||
                         (n == 2 && c == 0xC2 && static_cast<unsigned char>(text[i + 1]) < 0xA0);
    if (n == 0 || control) {
      n = n == 0 ? 1 : n;
      for (size_t k = 0; k < n; ++k) {
        const unsigned char b = static_cast<unsigned char>(text[i + k]);
        out += "\\x";
        out += kHex[b >> 4];
        out += kHex[b & 15];
      }
    } else {
      out.append(text, i, n);
    }
    i += n;
  }
  return out;
}

}  // namespace placedb
