#include "placedb/util/mapped_file.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
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
  }
  return file;  // the mapping keeps the file's pages when fd is closed
}

MappedFile::~MappedFile() {
  if (mapped_) ::munmap(const_cast<char*>(data_), size_);
}

}  // namespace placedb
