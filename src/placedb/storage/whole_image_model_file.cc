#include "placedb/storage/whole_image_model_file.h"

#include <cmath>
#include <cstddef>
#include <vector>

#include "placedb/storage/flat_file.h"
#include "placedb/util/check.h"
#include "placedb/util/file_io.h"

namespace placedb {
namespace {

constexpr char kMagic[8] = {'P', 'L', 'D', 'B', 'W', 'I', 'M', '\n'};

struct ModelHeader {
  flat_file::CommonHeader common;
  uint32_t width;
  uint32_t height;
  uint32_t input_dims;
  uint32_t output_dims;
  char reserved[72];
  uint64_t header_checksum;
};
static_assert(sizeof(ModelHeader) == flat_file::kHeaderBytes &&
                  offsetof(ModelHeader, width) == 32 &&
                  offsetof(ModelHeader, header_checksum) == flat_file::kHeaderChecksumOffset,
              "the whole-image model header's layout");

struct Sections {
  explicit Sections(uint64_t limit) : layout(limit) {}
  flat_file::Layout layout;
  uint64_t mean = 0, projection = 0;
};
Sections ModelSections(uint64_t input_dims, uint64_t output_dims, uint64_t limit) {
  Sections s(limit);
  s.mean = s.layout.Add(input_dims, sizeof(float));
  s.projection = s.layout.Add(input_dims * output_dims, sizeof(float));
  return s;
}

}  // namespace

void SaveWholeImageModel(const WholeImageModel& model, const std::string& path) {
  if (!HostIsLittleEndian()) PLACEDB_THROW_IO("placedb's files need a little-endian host");
  const auto in = static_cast<uint64_t>(model.input_dims());
  const auto out = static_cast<uint64_t>(model.output_dims());
  const Sections at = ModelSections(in, out, UINT64_MAX);
  char* w = nullptr;
  flat_file::Image image = flat_file::NewImage(at.layout.end(), &w);
  ModelHeader header{};
  header.width = static_cast<uint32_t>(model.width());
  header.height = static_cast<uint32_t>(model.height());
  header.input_dims = static_cast<uint32_t>(in);
  header.output_dims = static_cast<uint32_t>(out);
  std::memcpy(w, &header, sizeof(header));
  std::memcpy(w + at.mean, model.mean().data(), in * sizeof(float));
  std::memcpy(w + at.projection, model.projection().data(), in * out * sizeof(float));
  flat_file::Seal(w, at.layout.end(), kMagic, kWholeImageModelFormatVersion);
  flat_file::WriteImage(image, path);
}

std::shared_ptr<const WholeImageModel> ReadWholeImageModel(std::shared_ptr<const MappedFile> file,
                                                           const std::string& shown) {
  if (!HostIsLittleEndian()) PLACEDB_THROW_IO("placedb's files need a little-endian host");
  const flat_file::Image image = flat_file::MapImage(std::move(file));
  flat_file::CheckSealed(image, kMagic, kWholeImageModelFormatVersion, "whole-image model", shown);
  const auto header = flat_file::ReadHeader<ModelHeader>(image.data);
  auto bad_side = [](uint32_t v) { return v < 16 || v > 128 || v % 8 != 0; };
  if (bad_side(header.width) || bad_side(header.height)) {
    PLACEDB_THROW_CORRUPT(shown, ": thumbnails of ", header.width, " x ", header.height,
                          " (each a multiple of 8 in [16, 128])");
  }
  const int dims = HogRawDims(static_cast<int>(header.width), static_cast<int>(header.height));
  if (header.input_dims != static_cast<uint32_t>(dims)) {
    PLACEDB_THROW_CORRUPT(shown, ": ", header.input_dims, " input values for ", header.width, " x ",
                          header.height, " thumbnails (", dims, ")");
  }
  if (header.output_dims < 1 || header.output_dims > 4096) {
    PLACEDB_THROW_CORRUPT(shown, ": ", header.output_dims, " output values (1 to 4096)");
  }
  for (const char c : header.reserved) {
    if (c != 0) PLACEDB_THROW_CORRUPT(shown, ": reserved header bytes are not zero");
  }
  const Sections at = ModelSections(header.input_dims, header.output_dims, image.size);
  if (at.layout.overflowed() || at.layout.end() != image.size) {
    PLACEDB_THROW_CORRUPT(shown, ": its size does not fit its header (", image.size, " bytes)");
  }
  if (!at.layout.PaddingIsZero(image.data)) PLACEDB_THROW_CORRUPT(shown, ": padding is not zero");
  const float* mean = image.At<float>(at.mean);
  const float* projection = image.At<float>(at.projection);
  std::vector<float> m(mean, mean + header.input_dims);
  std::vector<float> p(projection, projection + uint64_t{header.input_dims} * header.output_dims);
  try {
    return std::make_shared<const WholeImageModel>(
        static_cast<int>(header.width), static_cast<int>(header.height),
        static_cast<int>(header.output_dims), std::move(m), std::move(p));
  } catch (const InvalidArgument& e) {
    PLACEDB_THROW_CORRUPT(shown, ": ", e.what());
  }
}

}  // namespace placedb
