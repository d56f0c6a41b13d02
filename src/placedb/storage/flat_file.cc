#include "placedb/storage/flat_file.h"

#include <algorithm>
#include <limits>
#include <new>

#include "placedb/util/check.h"
#include "placedb/util/checksum.h"
#include "placedb/util/file_io.h"

namespace placedb {

namespace flat_file {

Image NewImage(uint64_t bytes, char** writable) {
  PLACEDB_CHECK(bytes >= kHeaderBytes && bytes <= std::numeric_limits<size_t>::max() / 2,
                "a file image of ", bytes, " bytes");
  constexpr std::align_val_t kAlign{kAlignment};
  char* data = static_cast<char*>(::operator new(static_cast<size_t>(bytes), kAlign));
  Image image;
  image.owner = std::shared_ptr<char>(data, [](char* p) { ::operator delete(p, kAlign); });
  std::memset(data, 0, static_cast<size_t>(bytes));
  image.data = data;
  image.size = bytes;
  *writable = data;
  return image;
}

Image MapImage(std::shared_ptr<const MappedFile> file) {
  PLACEDB_CHECK(file != nullptr, "no mapped file");
  Image image;
  image.data = file->data();
  image.size = file->size();
  image.owner = std::move(file);
  return image;
}

uint64_t Layout::Add(uint64_t count, uint64_t item_bytes) {
  if (overflowed_) return 0;
  const uint64_t offset = (end_ + kAlignment - 1) / kAlignment * kAlignment;
  if (offset < end_ || offset > limit_ ||
      (item_bytes != 0 && count > (limit_ - offset) / item_bytes)) {
    overflowed_ = true;
    return 0;
  }
  if (offset > end_) padding_.emplace_back(end_, offset);
  end_ = offset + count * item_bytes;
  return offset;
}

bool Layout::PaddingIsZero(const char* data) const {
  return std::all_of(padding_.begin(), padding_.end(), [&](const auto& range) {
    return std::all_of(data + range.first, data + range.second, [](char c) { return c == 0; });
  });
}

namespace {
// Sets the file size and both checksums of an image whose other fields are
// written.
uint64_t SealChecksums(char* data, uint64_t size) {
  CommonHeader common;
  std::memcpy(&common, data, sizeof(common));
  common.file_bytes = size;
  common.payload_checksum =
      Checksum64(data + kHeaderBytes, static_cast<size_t>(size - kHeaderBytes));
  std::memcpy(data, &common, sizeof(common));
  const uint64_t checksum = Checksum64(data, kHeaderChecksumOffset);
  std::memcpy(data + kHeaderChecksumOffset, &checksum, sizeof(checksum));
  return checksum;
}
}  // namespace

uint64_t Seal(char* data, uint64_t size, const char (&magic)[8], uint32_t version) {
  CommonHeader common{};
  std::memcpy(common.magic, magic, sizeof(magic));
  common.version = version;
  common.header_bytes = static_cast<uint32_t>(kHeaderBytes);
  std::memcpy(data, &common, sizeof(common));
  return SealChecksums(data, size);
}

uint64_t Reseal(std::string* bytes) {
  if (bytes->size() < kHeaderBytes) return 0;
  return SealChecksums(bytes->data(), bytes->size());
}

void CheckSealed(const Image& image, const char (&magic)[8], uint32_t version, const char* kind,
                 const std::string& shown) {
  CheckSealedHeader(image, magic, version, kind, shown);
  CheckPayloadChecksum(image, shown);
}

void CheckPayloadChecksum(const Image& image, const std::string& shown) {
  CommonHeader common;
  std::memcpy(&common, image.data, sizeof(common));
  if (Checksum64(image.data + kHeaderBytes, static_cast<size_t>(image.size - kHeaderBytes)) !=
      common.payload_checksum) {
    PLACEDB_THROW_CORRUPT(shown, ": payload checksum mismatch (the file is corrupted)");
  }
}

void CheckSealedHeader(const Image& image, const char (&magic)[8], uint32_t version,
                       const char* kind, const std::string& shown) {
  const char* b = image.data;
  const uint64_t size = image.size;
  auto fail = [&](const auto&... what) { PLACEDB_THROW_CORRUPT(shown, ": ", what...); };
  // A file cut inside the magic (a prefix of it, or empty) is truncated, not
  // a different kind of file.
  if (size < sizeof(magic) && (size == 0 || std::memcmp(b, magic, size) == 0))
    fail("file is truncated (", size, " bytes)");
  if (size < sizeof(magic) || std::memcmp(b, magic, sizeof(magic)) != 0)
    fail("not a placedb ", kind, " file (wrong magic)");
  if (size < kHeaderBytes) fail("file is truncated (", size, " bytes)");
  CommonHeader common;
  std::memcpy(&common, b, sizeof(common));
  if (common.version != version) {
    fail(kind, " format version ", common.version, " is not supported (this placedb reads version ",
         version, ")");
  }
  if (common.header_bytes != kHeaderBytes) fail("bad header size ", common.header_bytes);
  if (common.file_bytes != size) {
    fail(size < common.file_bytes ? "file is truncated" : "file has unexpected trailing bytes",
         " (", size, " bytes, the header says ", common.file_bytes, ")");
  }
  uint64_t header_checksum;
  std::memcpy(&header_checksum, b + kHeaderChecksumOffset, sizeof(header_checksum));
  if (Checksum64(b, kHeaderChecksumOffset) != header_checksum)
    fail("header checksum mismatch (the file is corrupted)");
}

void WriteImage(const Image& image, const std::string& path) {
  AtomicFileWriter out(path);
  out.Write(image.data, static_cast<size_t>(image.size));
  out.Commit();
}

}  // namespace flat_file

}  // namespace placedb
