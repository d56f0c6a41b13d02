// placedb's flat index files (the vocabulary and the bag-of-words index, in
// retrieval/): a 128-byte header, a struct that starts with the CommonHeader
// and ends with the header checksum, then 64-byte-aligned sections whose
// offsets follow from the header's counts (Layout), so a reader needs no
// section table. Files are used in place from a memory map.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "placedb/util/mapped_file.h"

namespace placedb {

// The helpers of placedb's flat index files (the vocabulary and the
// bag-of-words index): a 128-byte header, a struct that starts with the
// CommonHeader and ends with the header checksum, then 64-byte-aligned
// sections whose offsets follow from the header's counts (Layout), so a
// reader needs no section table.
namespace flat_file {

constexpr size_t kHeaderBytes = 128;
constexpr size_t kAlignment = 64;
// The last 8 header bytes: XXH3-64 of the header bytes before them.
constexpr size_t kHeaderChecksumOffset = kHeaderBytes - sizeof(uint64_t);

// The first 32 bytes of every header.
struct CommonHeader {
  char magic[8];
  uint32_t version;
  uint32_t header_bytes;      // kHeaderBytes
  uint64_t file_bytes;        // the whole file
  uint64_t payload_checksum;  // XXH3-64 of bytes [kHeaderBytes, file_bytes)
};

// A format's header struct, copied out of a file image (at least
// kHeaderBytes; it need not be aligned). The formats are little-endian:
// Train, Build and Open refuse big-endian hosts.
template <typename Header>
Header ReadHeader(const char* data) {
  static_assert(sizeof(Header) == kHeaderBytes && std::is_trivially_copyable<Header>::value,
                "a flat file header is a 128-byte struct");
  Header header;
  std::memcpy(&header, data, sizeof(header));
  return header;
}

// The bytes of a file: a read-only memory map, or an image built in memory
// (64-byte aligned). `owner` keeps them alive, so copies and moves of an
// Image (and of what points into it) stay valid.
struct Image {
  std::shared_ptr<const void> owner;
  const char* data = nullptr;
  uint64_t size = 0;

  template <typename T>
  const T* At(uint64_t offset) const {
    return reinterpret_cast<const T*>(data + offset);
  }
};

// A zero-filled image of `bytes` bytes; `*writable` receives its bytes.
Image NewImage(uint64_t bytes, char** writable);
// The image of a mapped file (kept alive by the image).
Image MapImage(std::shared_ptr<const MappedFile> file);

// Where the sections of a file lie: each at the next multiple of kAlignment
// after the previous one, the first after the header, with zeros between
// them. A section that would end beyond `limit` (the file's size, for counts
// read from an untrusted header) sets overflowed() instead of wrapping
// around.
class Layout {
 public:
  explicit Layout(uint64_t limit) : limit_(limit) {}
  // The offset of a new section of `count` items of `item_bytes` each (0
  // once overflowed).
  uint64_t Add(uint64_t count, uint64_t item_bytes);
  uint64_t end() const { return end_; }
  bool overflowed() const { return overflowed_; }
  // Whether the padding before each section is zero in `data` (a file of at
  // least end() bytes).
  bool PaddingIsZero(const char* data) const;

 private:
  uint64_t limit_;
  uint64_t end_ = kHeaderBytes;
  bool overflowed_ = false;
  std::vector<std::pair<uint64_t, uint64_t>> padding_;  // [begin, end) ranges
};

// Fills in the common header (magic, version, header bytes, file bytes =
// `size`, payload checksum) and then the header checksum of an image whose
// format fields and sections are written; returns the header checksum.
uint64_t Seal(char* data, uint64_t size, const char (&magic)[8], uint32_t version);

// Recomputes the file bytes and both checksums of a file image in `bytes`,
// keeping its magic and version; returns the header checksum (0 when the
// image is shorter than a header). For tests that damage a file so that the
// parser itself, not the checksums, must catch it.
uint64_t Reseal(std::string* bytes);
// The same on a copy of `bytes` with `value` written at `offset` (offset +
// sizeof(T) <= bytes.size()).
template <typename T>
std::string Patched(std::string bytes, uint64_t offset, const T& value) {
  static_assert(std::is_trivially_copyable<T>::value, "flat values only");
  std::memcpy(&bytes[offset], &value, sizeof(T));
  Reseal(&bytes);
  return bytes;
}

// Checks what Seal wrote, before anything else is read: magic (a wrong one
// says "not a placedb <kind> file"), version, header size, file size
// (truncated or trailing bytes) and both checksums. Throws
// CorruptDatabase "<shown>: <what is wrong>".
void CheckSealed(const Image& image, const char (&magic)[8], uint32_t version, const char* kind,
                 const std::string& shown);
// CheckSealed in two parts, for a caller that checks the payload's
// checksum while it reads the payload on other threads (the reads must not
// trust it until both have passed): all but the payload's checksum, then
// that checksum ("payload checksum mismatch (the file is corrupted)").
void CheckSealedHeader(const Image& image, const char (&magic)[8], uint32_t version,
                       const char* kind, const std::string& shown);
void CheckPayloadChecksum(const Image& image, const std::string& shown);

// Writes the image to `path` crash-safely (AtomicFileWriter: temporary file,
// fsync, rename).
void WriteImage(const Image& image, const std::string& path);

}  // namespace flat_file

}  // namespace placedb
