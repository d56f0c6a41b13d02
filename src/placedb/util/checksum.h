// 64-bit checksums of file contents (XXH3 from Debian's libxxhash, used
// header-only): fast enough (tens of GB/s) to verify a whole database on
// every open, and a far stronger check against damage than CRC-32.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace placedb {

uint64_t Checksum64(const void* data, size_t size);

// The same checksum of data fed in pieces.
class Checksum64Stream {
 public:
  Checksum64Stream();
  ~Checksum64Stream();
  Checksum64Stream(const Checksum64Stream&) = delete;
  Checksum64Stream& operator=(const Checksum64Stream&) = delete;

  void Update(const void* data, size_t size);
  uint64_t Digest() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// 16 lower-case hex digits.
std::string ChecksumHex(uint64_t checksum);

}  // namespace placedb
