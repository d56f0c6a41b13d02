#include "placedb/util/mapped_file.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include "placedb/util/check.h"
#include "placedb/util/file_io.h"

namespace placedb {

std::shared_ptr<const MappedFile> MappedFile::Open(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) PLACEDB_THROW_READ_ERROR(errno, "cannot open ", path);
  try {
    auto file = FromFd(fd, path);
    ::close(fd);
    return file;
  } catch (...) {
    ::close(fd);
    throw;
  }
}

std::shared_ptr<const MappedFile> MappedFile::FromFd(int fd, const std::string& what) {
  struct stat st;
  if (::fstat(fd, &st) != 0) PLACEDB_THROW_IO("cannot stat ", what, ": ", std::strerror(errno));
  if (!S_ISREG(st.st_mode)) PLACEDB_THROW_INVALID(what, " is not a regular file");
  std::shared_ptr<MappedFile> file(new MappedFile());
  file->size_ = static_cast<size_t>(st.st_size);
  if (file->size_ > 0) {
    void* p = ::mmap(nullptr, file->size_, PROT_READ, MAP_PRIVATE, fd, 0);
    if (p == MAP_FAILED) PLACEDB_THROW_IO("cannot map ", what, ": ", std::strerror(errno));
    file->data_ = static_cast<const char*>(p);
    file->mapped_ = true;
    // Kept for ReadAt (the caller closes `fd`).
    file->fd_ = ::fcntl(fd, F_DUPFD_CLOEXEC, 0);
    if (file->fd_ < 0) PLACEDB_THROW_IO("cannot keep ", what, " open: ", std::strerror(errno));
  }
  file->what_ = what;
  return file;  // the mapping keeps the file's pages when fd is closed
}

void MappedFile::ReadAt(size_t offset, size_t length, void* dst) const {
  if (offset > size_ || length > size_ - offset) {
    PLACEDB_THROW_INVALID("bytes [", offset, ", ", offset + length, ") are outside ", what_, " (",
                          size_, " bytes)");
  }
  char* out = static_cast<char*>(dst);
  while (length > 0) {
    const ssize_t n = ::pread(fd_, out, length, static_cast<off_t>(offset));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) PLACEDB_THROW_IO("cannot read ", what_, ": ", std::strerror(errno));
    // The file shrank under its mapping (it is never written in place).
    if (n == 0) PLACEDB_THROW_IO("cannot read ", what_, ": it ends before byte ", offset);
    out += n;
    offset += static_cast<size_t>(n);
    length -= static_cast<size_t>(n);
  }
}

void MappedFile::Prefetch(const std::atomic<bool>& stop) const {
  if (!mapped_) return;
  constexpr size_t kChunk = size_t{16} << 20;
  for (size_t at = 0; at < size_ && !stop.load(std::memory_order_relaxed); at += kChunk) {
    // Advice only: an error (memory pressure) leaves the reads to the queries.
    ::madvise(const_cast<char*>(data_) + at, std::min(kChunk, size_ - at), MADV_WILLNEED);
  }
}

void MappedFile::ReleaseResidentPages(size_t offset, size_t length) const {
  if (!mapped_ || offset >= size_) return;
  const size_t end = offset + std::min(length, size_ - offset);
  const size_t page = static_cast<size_t>(::sysconf(_SC_PAGESIZE));
  const size_t first = offset / page * page;  // the mapping starts on a page
  ::madvise(const_cast<char*>(data_) + first, end - first, MADV_DONTNEED);
}

uint64_t ProcessFileBackedResidentBytes() {
  const int fd = ::open("/proc/self/statm", O_RDONLY | O_CLOEXEC);
  if (fd < 0) return 0;
  char text[256];
  const ssize_t n = ::read(fd, text, sizeof(text) - 1);
  ::close(fd);
  if (n <= 0) return 0;
  text[n] = '\0';
  // size resident shared text lib data dt, in pages; "shared" is the
  // file-backed (and shared memory) part of the resident set.
  unsigned long long size = 0, resident = 0, shared = 0;
  if (std::sscanf(text, "%llu %llu %llu", &size, &resident, &shared) != 3) return 0;
  return static_cast<uint64_t>(shared) * static_cast<uint64_t>(::sysconf(_SC_PAGESIZE));
}

MappedFile::~MappedFile() {
  if (mapped_) ::munmap(const_cast<char*>(data_), size_);
  if (fd_ >= 0) ::close(fd_);
}

}  // namespace placedb
