// File helpers: whole-file reads, crash-safe writes (temporary file, fsync,
// rename), directories read as one, and little-endian binary encoding.
#pragma once

#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <type_traits>
#include <vector>

#include "placedb/util/check.h"

namespace placedb {

// Reads a whole file. Throws NotFound when nothing is at `path`,
// InvalidArgument when it is a directory, IoError when it cannot be read.
std::string ReadFileToString(const std::string& path);

namespace internal {
// Throws the error of a system call that failed with `err` on an input path:
// NotFound when nothing is there (ENOENT, ENOTDIR: a path through a file),
// else IoError (permissions, a failing device). `message` is followed by
// ": <strerror>".
[[noreturn]] void ThrowReadError(int err, const std::string& message, std::string where);
}  // namespace internal

// An input file or folder could not be opened or read (errno `err`): NotFound
// or IoError (internal::ThrowReadError). An output that cannot be written is
// always PLACEDB_THROW_IO: a missing parent folder is a failed write, not a
// missing input.
#define PLACEDB_THROW_READ_ERROR(err, ...)                                                  \
  ::placedb::internal::ThrowReadError((err), ::placedb::internal::JoinMessage(__VA_ARGS__), \
                                      ::placedb::internal::SourceLocation(__FILE__, __LINE__))

// Writes all of `data` to the open descriptor `fd`, retrying short writes
// and EINTR; false with errno set on an error.
bool WriteAll(int fd, const char* data, size_t size);

// Writes `data` to `path` so that a crash leaves either the old file or the new
// one, never a torn file: write to a temporary sibling (TempPathFor), fsync,
// rename, fsync the directory. The temporary file is removed on any error.
// Only a regular file (or a new path) is replaced: a path that is a symlink,
// a character device, a FIFO or a socket (`/dev/stdout`, `/dev/fd/1`, a named
// pipe) is opened and written as a stream, never replaced; a directory is
// InvalidArgument. A failed write throws IoError naming the path.
void WriteFileAtomic(const std::string& path, const std::string& data);

// fsyncs a directory so that renames inside it are durable.
void SyncDirectory(const std::string& dir);

// A temporary sibling of `path` for a crash-safe write:
// "<path>.tmp.<pid>.<n>", unique within this process (n counts up) and
// between processes (pid).
std::string TempPathFor(const std::string& path);
// Whether `name` (a file name) is a temporary file name of TempPathFor (or of
// earlier versions, "<name>.tmp.<pid>"); its process id in `*pid`.
bool IsTempFileName(const std::string& name, long* pid = nullptr);
// Whether process `pid` is gone (so its temporary files are debris).
bool ProcessIsGone(long pid);
// Removes `path` when it is a regular file (never a symlink, which is not
// followed, nor anything else); false when it was not removed. Errors are
// ignored (best effort, for sweeping).
bool RemoveRegularFile(const std::string& path);

// A file written through a buffer into a temporary sibling (TempPathFor) and
// moved to `path` by Commit (fsync, rename, fsync of the directory): a crash
// leaves the old file or the new one, never a torn one. Destroyed uncommitted
// (an error, an exception), it removes the temporary file. `path` must be a
// regular file or a new path (anything else is InvalidArgument: this writer
// fills its header in last, which a stream cannot take); a failed write is
// IoError. Not thread-safe.
class AtomicFileWriter {
 public:
  explicit AtomicFileWriter(std::string path);
  ~AtomicFileWriter();
  AtomicFileWriter(const AtomicFileWriter&) = delete;
  AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;

  void Write(const void* data, size_t size);
  // Zeros up to a multiple of `alignment` bytes.
  void Align(size_t alignment);
  // Overwrites bytes already written (a header filled in last).
  void WriteAt(uint64_t offset, const void* data, size_t size);
  uint64_t position() const { return position_; }
  void Commit();
  // Commits under another name, `path` (a content name known only at the
  // end), with the same checks and durability as Commit.
  void CommitAs(const std::string& path);

 private:
  void Flush();

  std::string path_, tmp_;
  int fd_ = -1;
  std::string buffer_;
  uint64_t position_ = 0;
  bool committed_ = false;
};

class MappedFile;
class DirectoryHandle;

// Removes, directly inside `dir`, the temporary files (IsTempFileName) of
// processes that are gone; returns how many. Errors are ignored: sweeping is
// best effort and never fails the caller.
size_t SweepTempFiles(const DirectoryHandle& dir);

// A directory opened once: files read relative to it come from the same
// directory even if its path is renamed or replaced meanwhile.
class DirectoryHandle {
 public:
  // Throws NotFound when `path` is not a directory, IoError when it cannot be
  // opened.
  explicit DirectoryHandle(const std::string& path);
  ~DirectoryHandle();
  DirectoryHandle(const DirectoryHandle&) = delete;
  DirectoryHandle& operator=(const DirectoryHandle&) = delete;

  // The directory `name` directly inside `parent`, opened without following
  // a symlink: nullptr when `name` is missing, a symlink or not a directory
  // (so a writer never reaches outside the folder it owns through a link);
  // other errors throw IoError.
  static std::unique_ptr<DirectoryHandle> OpenChild(const DirectoryHandle& parent,
                                                    const std::string& name);

  const std::string& path() const { return path_; }
  // The names directly inside, "." and ".." left out, in no order. Errors
  // throw IoError.
  std::vector<std::string> List() const;
  // Removes `name` when it is a regular file directly inside (never a
  // symlink, which is not followed, nor anything else); false when it was
  // not removed. Errors are ignored (best effort, for sweeping).
  bool RemoveRegularFile(const std::string& name) const;
  // Writes `data` to the file `name` directly inside, crash-safely as
  // WriteFileAtomic does (a temporary sibling, fsync, renameat, fsync of this
  // directory), all relative to this directory's descriptor: a symlink at
  // `name` is replaced, never followed. A failed write throws IoError.
  void WriteFileAtomic(const std::string& name, const std::string& data) const;
  // The whole file `name`, or false when it does not exist (other errors
  // throw IoError). At most `max_bytes` are accepted: a larger file is
  // CorruptDatabase (this reads the small files of a database: manifests).
  bool ReadFile(const std::string& name, std::string* out, size_t max_bytes) const;
  // The file `name` mapped read-only, or nullptr when it does not exist. A
  // name that is not a regular file is CorruptDatabase (a database's files
  // are named by its manifest); other errors throw IoError.
  std::shared_ptr<const MappedFile> MapFile(const std::string& name) const;

 private:
  DirectoryHandle(std::string path, int fd) : path_(std::move(path)), fd_(fd) {}
  std::string path_;
  int fd_ = -1;
};

// An exclusive advisory lock (flock) on a directory, held while the object
// lives: one writer per database folder across processes. Taking it needs
// only read access to the folder (no lock file is created).
class DirectoryLock {
 public:
  // The lock, or nullptr when another open file (process or session) holds
  // it. Throws NotFound when `dir` does not exist, IoError when it cannot be
  // opened or locked.
  static std::unique_ptr<DirectoryLock> TryLock(const std::string& dir);
  ~DirectoryLock();
  DirectoryLock(const DirectoryLock&) = delete;
  DirectoryLock& operator=(const DirectoryLock&) = delete;

 private:
  explicit DirectoryLock(int fd) : fd_(fd) {}
  int fd_ = -1;
};

// Size of a file in bytes, 0 if it does not exist.
uint64_t FileSize(const std::string& path);
// Sum of the sizes of the regular files directly inside `dir` (0 if missing).
uint64_t DirectorySize(const std::string& dir);

static_assert(sizeof(float) == 4 && sizeof(double) == 8, "IEEE-754 floats expected");

// Appends fixed-width little-endian values and flat arrays to a byte buffer.
// placedb targets little-endian hosts (x86-64, ARM64); the format is defined
// as little-endian and the reader rejects a big-endian host at run time.
class BinaryWriter {
 public:
  template <typename T>
  void Put(const T& value) {
    static_assert(std::is_trivially_copyable<T>::value, "flat values only");
    const char* bytes = reinterpret_cast<const char*>(&value);
    buffer_.append(bytes, sizeof(T));
  }
  template <typename T>
  void PutArray(const T* values, size_t count) {
    static_assert(std::is_trivially_copyable<T>::value, "flat values only");
    buffer_.append(reinterpret_cast<const char*>(values), sizeof(T) * count);
  }
  void PutBytes(const void* data, size_t size) {
    buffer_.append(reinterpret_cast<const char*>(data), size);
  }
  // Pads with zeros to a multiple of `alignment` bytes (for memory mapping).
  void Align(size_t alignment) {
    while (buffer_.size() % alignment != 0) buffer_.push_back('\0');
  }
  size_t size() const { return buffer_.size(); }
  const std::string& buffer() const { return buffer_; }
  std::string& mutable_buffer() { return buffer_; }

 private:
  std::string buffer_;
};

// Reads what BinaryWriter wrote; every read is bounds-checked and a short
// buffer throws CorruptDatabase (a truncated file) mentioning `what` (the
// file name).
class BinaryReader {
 public:
  BinaryReader(const char* data, size_t size, std::string what)
      : data_(data), size_(size), what_(std::move(what)) {}

  template <typename T>
  T Get() {
    static_assert(std::is_trivially_copyable<T>::value, "flat values only");
    T value;
    Need(sizeof(T));
    std::memcpy(&value, data_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    return value;
  }
  template <typename T>
  void GetArray(T* out, size_t count) {
    static_assert(std::is_trivially_copyable<T>::value, "flat values only");
    const size_t bytes = sizeof(T) * count;
    if (count != 0 && bytes / count != sizeof(T)) PLACEDB_THROW_CORRUPT(what_, ": array too large");
    Need(bytes);
    if (bytes != 0) std::memcpy(out, data_ + pos_, bytes);
    pos_ += bytes;
  }
  void GetBytes(void* out, size_t size) { GetArray(static_cast<char*>(out), size); }
  // Moves past `bytes` bytes (bounds-checked like a read).
  void Skip(size_t bytes) {
    Need(bytes);
    pos_ += bytes;
  }
  void Align(size_t alignment) {
    const size_t pad = (alignment - pos_ % alignment) % alignment;
    Need(pad);
    pos_ += pad;
  }
  size_t position() const { return pos_; }
  size_t remaining() const { return size_ - pos_; }

 private:
  void Need(size_t bytes) const {
    if (bytes > size_ - pos_) {
      PLACEDB_THROW_CORRUPT(what_, ": file is truncated (needed ", bytes, " more bytes at offset ",
                            pos_, ", file has ", size_, ")");
    }
  }
  const char* data_;
  size_t size_;
  size_t pos_ = 0;
  std::string what_;
};

// True on little-endian hosts (the only ones the binary formats support).
bool HostIsLittleEndian();

// Names read from files (a database's stored-image names) become paths only
// when this holds: a plain file name of 1 to 255 bytes from the POSIX
// portable set [A-Za-z0-9._-], not starting with '.' (so never "." or "..",
// no hidden or temporary-looking names), with no separator, control
// character, NUL or byte above 0x7E. Such a name joined to a folder stays in
// that folder.
bool IsPlainFileName(const std::string& name);

// Whether `text` is well-formed UTF-8 (RFC 3629: no overlong forms, no
// surrogates, nothing above U+10FFFF).
bool IsValidUtf8(const std::string& text);

// `text` safe to write to a terminal: control characters (C0, DEL, C1) and
// bytes that are not part of well-formed UTF-8 become "\xNN" (two lowercase
// hex digits); everything else (printable ASCII, other UTF-8) is kept. Every
// CLI print of a path or string read from a file goes through it.
std::string EscapeForTerminal(const std::string& text);

}  // namespace placedb
