// A read-only memory mapping of a whole file, so flat arrays in it can be used
// in place, without reading and copying them.
#pragma once

#include <cstddef>
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

 private:
  MappedFile() = default;
  const char* data_ = nullptr;
  size_t size_ = 0;
  bool mapped_ = false;
};

}  // namespace placedb
