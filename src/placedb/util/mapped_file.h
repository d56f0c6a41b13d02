// A read-only memory mapping of a whole file, so flat arrays in it can be used
// in place, without reading and copying them.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace placedb {

class MappedFile {
 public:
  // Maps `path` read-only. Throws NotFound when nothing is at `path`,
  // InvalidArgument when it is not a regular file, IoError when it cannot be
  // opened or mapped. An empty file gives an empty mapping.
  static std::shared_ptr<const MappedFile> Open(const std::string& path);
  // Maps the open file `fd` (which the caller keeps and closes); `what` names
  // it in errors.
  static std::shared_ptr<const MappedFile> FromFd(int fd, const std::string& what);

  ~MappedFile();
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;

  const char* data() const { return data_; }
  size_t size() const { return size_; }

  // Asks the kernel to read the file into its page cache (madvise
  // MADV_WILLNEED, 16 MiB at a time, the calling thread waiting for each
  // request to be queued) until it is all asked for or `stop` is set: later
  // reads of the mapping find their pages in memory instead of waiting for
  // the disk. Maps nothing into the process (its resident memory is
  // unchanged); the page cache is the kernel's, shared, and given back under
  // memory pressure.
  void Prefetch(const std::atomic<bool>& stop) const;
  // Lets go of the pages of the mapping that are resident in this process
  // (madvise MADV_DONTNEED): the process's resident memory drops; the pages
  // stay in the page cache while the kernel keeps them, and the next read
  // maps them again (a minor fault) or reads them from the file. Safe while
  // other threads read the mapping: it is read-only, nothing is lost.
  void ReleaseResidentPages() const { ReleaseResidentPages(0, size_); }
  // The same for the pages of bytes [offset, offset + length) (clipped to
  // the file; pages partly inside count).
  void ReleaseResidentPages(size_t offset, size_t length) const;
  // Copies bytes [offset, offset + length) of the file into `dst` by reading
  // the file (pread on a descriptor the mapping keeps), not the mapping: the
  // bytes are the mapping's (the same page cache pages), but nothing is
  // mapped into the process, whose resident memory is unchanged. For a
  // thread that checks a file's blocks in the background. InvalidArgument
  // for a range outside the file, IoError when the read fails.
  void ReadAt(size_t offset, size_t length, void* dst) const;

 private:
  MappedFile() = default;
  const char* data_ = nullptr;
  size_t size_ = 0;
  bool mapped_ = false;
  int fd_ = -1;       // a duplicate of the mapped file's descriptor (ReadAt); -1 when empty
  std::string what_;  // the file, in errors
};

// This process's file-backed resident memory (mapped files; shared memory
// counts too), bytes, from /proc/self/statm; 0 when it cannot be read.
uint64_t ProcessFileBackedResidentBytes();

}  // namespace placedb
