// The whole-image model of a database (feature/whole_image_model.h) on disk:
// `whole_image_model.bin` in the database folder, named by the manifest's
// `whole_image_model`, written by a build of a HOG channel, read by every
// session that opens it. A flat file (storage/flat_file.h): a 128-byte
// header (the common header, then u32 thumbnail width, u32 height, u32 input
// dims D = HogRawDims(width, height), u32 output dims d, zeros, the header
// checksum), then the mean (D float32) and the projection (d x D float32,
// row-major), each 64-byte aligned.
#pragma once

#include <memory>
#include <string>

#include "placedb/feature/whole_image_model.h"
#include "placedb/util/mapped_file.h"

namespace placedb {

constexpr char kWholeImageModelFile[] = "whole_image_model.bin";
constexpr uint32_t kWholeImageModelFormatVersion = 1;

// Writes `model` to `path` crash-safely.
void SaveWholeImageModel(const WholeImageModel& model, const std::string& path);

// The model in `file` (shown in errors as `shown`). Every field, size, the
// checksums and every value (finite, below 1e6) are checked: anything else
// is CorruptDatabase naming `shown`.
std::shared_ptr<const WholeImageModel> ReadWholeImageModel(std::shared_ptr<const MappedFile> file,
                                                           const std::string& shown);

}  // namespace placedb
