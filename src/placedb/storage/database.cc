#include "placedb/storage/database.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <filesystem>
#include <functional>
#include <mutex>
#include <numeric>
#include <type_traits>
#include <unordered_set>

#include "placedb/storage/compact_keypoint.h"
#include "placedb/storage/keyframe_file.h"
#include "placedb/util/check.h"
#include "placedb/util/checksum.h"
#include "placedb/util/file_io.h"
#include "placedb/util/json_reader.h"
#include "placedb/util/parallel.h"

namespace placedb {
namespace fs = std::filesystem;
namespace kf = keyframe_file;
namespace ckp = compact_keypoint;

// What checks a version 3 file's features when they are first used
// (Database::Keypoints, "Integrity"): each kept keyframe's two block
// checksums, a flag per keyframe once checked, and the sections VerifyAll
// checks whole.
struct Database::LazyCheck {
  struct Section {
    const char* data = nullptr;
    uint64_t bytes = 0, checksum = 0;
  };
  std::string shown;                       // the file, in errors
  std::vector<uint64_t> sums;              // 2 per kept keyframe: keypoints, descriptors
  std::unique_ptr<std::atomic<uint8_t>[]>  // 1 once keyframe i is checked
      checked;
  Section keypoints, descriptors, whole_image;
  std::atomic<bool> whole_image_checked{false};
  std::mutex whole_image_mutex;
};

// Keypoints are used in place from the file: its records are cv::KeyPoint.
static_assert(std::is_standard_layout<cv::KeyPoint>::value, "cv::KeyPoint layout");
static_assert(sizeof(cv::KeyPoint) == kf::kKeypointRecordBytes, "cv::KeyPoint is 28 bytes");
static_assert(offsetof(cv::KeyPoint, pt) == 0 && offsetof(cv::KeyPoint, size) == 8 &&
                  offsetof(cv::KeyPoint, angle) == 12 && offsetof(cv::KeyPoint, response) == 16 &&
                  offsetof(cv::KeyPoint, octave) == 20 && offsetof(cv::KeyPoint, class_id) == 24,
              "cv::KeyPoint field order");

namespace {

constexpr size_t kMaxPathBytes = 65536;
// What asking a keyframe table (LoadContents::kKeyframeTable) for features
// says: the caller opened it so.
constexpr char kNoFeatures[] = "the database was opened as a keyframe table, without features";

// Little-endian field access in a byte image (the host is checked to be
// little-endian before any file is read or written).
template <typename T>
T Field(const char* base, size_t offset) {
  T value;
  std::memcpy(&value, base + offset, sizeof(T));
  return value;
}
template <typename T>
void SetField(char* base, size_t offset, T value) {
  std::memcpy(base + offset, &value, sizeof(T));
}

bool Finite(double v) { return std::isfinite(v); }

// Offsets inside a 152-byte keyframe record.
namespace rec {
constexpr size_t kId = 0, kCropChannel = 4, kCropX = 8, kCropY = 12, kCropW = 16, kCropH = 20,
                 kOrigW = 24, kOrigH = 28, kStoredW = 32, kStoredH = 36, kTimestamp = 40,
                 kScale = 48, kHasPose = 56, kPositive = 60, kTx = 64, kQx = 88,
                 kFeatureOffset = 120, kFeatureCount = 128, kSourceLen = 132, kStringOffset = 136,
                 kImageLen = 144, kReserved = 148;
}  // namespace rec

// The header checksum: header bytes [0, 56) then the section table.
uint64_t HeaderChecksum(const char* bytes, uint32_t num_sections) {
  Checksum64Stream s;
  s.Update(bytes, kf::kChecksumOffset);
  s.Update(bytes + kf::kHeaderBytes, static_cast<size_t>(num_sections) * kf::kSectionEntryBytes);
  return s.Digest();
}

}  // namespace

std::string CheckKeyframe(const Keyframe& k) {
  if (k.id < 1) return "id " + std::to_string(k.id) + " is not >= 1";
  if (k.crop_channel < -1 || k.crop_channel > 2)
    return "crop channel " + std::to_string(k.crop_channel) + " is not in [-1, 2]";
  if (k.original_size.width < 0 || k.original_size.height < 0 || k.stored_size.width < 0 ||
      k.stored_size.height < 0) {
    return "an image size is negative";
  }
  if (k.crop.x < 0 || k.crop.y < 0 || k.crop.width < 0 || k.crop.height < 0)
    return "the crop rectangle is negative";
  constexpr int kMaxSide = 1 << 20;
  if (k.original_size.width > kMaxSide || k.original_size.height > kMaxSide ||
      k.stored_size.width > kMaxSide || k.stored_size.height > kMaxSide) {
    return "an image side is larger than 2^20 pixels";
  }
  if (k.original_size.width > 0 && k.original_size.height > 0 &&
      (int64_t{k.crop.x} + k.crop.width > k.original_size.width ||
       int64_t{k.crop.y} + k.crop.height > k.original_size.height)) {
    return "the crop rectangle leaves the original image";
  }
  if (!(k.scale > 0.0 && k.scale <= 64.0)) return "scale is not in (0, 64]";
  if (!Finite(k.timestamp)) return "timestamp is not finite";
  if (k.pose) {
    const Pose& p = *k.pose;
    if (!p.translation.allFinite() || !p.rotation.coeffs().allFinite())
      return "the pose is not finite";
    if (std::abs(p.rotation.norm() - 1.0) > 1e-3)
      return "the pose's quaternion is not of unit length";
  }
  if (k.source.size() > kMaxPathBytes || k.image_file.size() > kMaxPathBytes)
    return "a path is longer than 64 KiB";
  if (k.source.find('\0') != std::string::npos) return "the source path holds a NUL byte";
  if (!IsStoredImageName(k.image_file)) {
    return "stored image name '" + EscapeForTerminal(k.image_file) +
           "' is not images/<plain file name> (a name inside the database's images folder)";
  }
  return "";
}

bool IsStoredImageName(const std::string& name) {
  constexpr size_t kPrefix = sizeof(kStoredImageFolder) - 1;
  return name.empty() ||
         (name.size() > kPrefix + 1 && name.compare(0, kPrefix, kStoredImageFolder) == 0 &&
          name[kPrefix] == '/' && IsPlainFileName(name.substr(kPrefix + 1)));
}

std::string CheckKeypoints(const cv::KeyPoint* keypoints, size_t count, cv::Size image_size) {
  constexpr float kMaxSide = 1 << 20;  // CheckKeyframe's largest image side
  const bool known = image_size.width > 0 && image_size.height > 0;
  const float tolerance = kKeypointTolerancePx;
  const float max_x = (known ? static_cast<float>(image_size.width) : kMaxSide) + tolerance;
  const float max_y = (known ? static_cast<float>(image_size.height) : kMaxSide) + tolerance;
  for (size_t i = 0; i < count; ++i) {
    const cv::KeyPoint& kp = keypoints[i];
    if (!std::isfinite(kp.pt.x) || !std::isfinite(kp.pt.y) || !std::isfinite(kp.size) ||
        !std::isfinite(kp.angle) || !std::isfinite(kp.response)) {
      return "has a keypoint that is not finite (keypoint " + std::to_string(i) + ")";
    }
    if (!(kp.pt.x >= -tolerance && kp.pt.x <= max_x && kp.pt.y >= -tolerance && kp.pt.y <= max_y)) {
      return "has a keypoint outside its " +
             (known ? "stored image (" + std::to_string(image_size.width) + "x" +
                          std::to_string(image_size.height) + ")"
                    : std::string("largest possible image (2^20 pixels a side)")) +
             ": keypoint " + std::to_string(i) + " at (" + std::to_string(kp.pt.x) + ", " +
             std::to_string(kp.pt.y) + ")";
    }
  }
  return "";
}

bool AllFinite(const float* values, size_t count) {
  // A float is finite when its exponent bits are not all ones: the largest
  // magnitude bit pattern tells for the whole array (a max reduction, which
  // the compiler vectorises).
  uint32_t largest = 0;
  for (size_t i = 0; i < count; ++i) {
    uint32_t bits;
    std::memcpy(&bits, values + i, 4);
    bits &= 0x7fffffffu;
    largest = bits > largest ? bits : largest;
  }
  return largest < 0x7f800000u;
}

Database::Database(FeatureType type, int descriptor_bytes, int whole_image_dims)
    : feature_type_(type),
      descriptor_bytes_(descriptor_bytes),
      whole_image_dims_(whole_image_dims) {
  if (whole_image_dims != 0 && (whole_image_dims < static_cast<int>(kf::kMinWholeImageDims) ||
                                whole_image_dims > static_cast<int>(kf::kMaxWholeImageDims))) {
    PLACEDB_THROW_INVALID("whole-image rows of ", whole_image_dims, " values (0, or [",
                          kf::kMinWholeImageDims, ", ", kf::kMaxWholeImageDims, "])");
  }
  const bool ok = type == FeatureType::kOrb ? descriptor_bytes == 32
                                            : (descriptor_bytes == 256 || descriptor_bytes == 512);
  if (!ok) {
    PLACEDB_THROW_INVALID(FeatureTypeName(type), " descriptors cannot be ", descriptor_bytes,
                          " bytes wide");
  }
}

int Database::IndexOfId(int32_t id) const {
  const auto it = index_of_id_.find(id);
  return it == index_of_id_.end() ? -1 : it->second;
}

std::vector<cv::KeyPoint> Database::Keypoints(size_t index) const {
  if (!has_features_) PLACEDB_THROW_INVALID(kNoFeatures);
  const size_t count = feature_count_[index];
  if (mapping_ && mapped_compact_keypoints_ != nullptr) {
    thread_local std::vector<uint8_t> buffer;
    const char* records;
    if (reads_features()) {
      const size_t at = ReadFeatures(index, false, true, &buffer);  // resizes the buffer: first
      records = reinterpret_cast<const char*>(buffer.data()) + at;
    } else {
      EnsureChecked(index);
      records = mapped_compact_keypoints_ + row_offset_[index] * ckp::kRecordBytes;
    }
    std::vector<cv::KeyPoint> out(count);
    const int bits = ckp::FractionBits(keyframes_[index].stored_size);  // checked on open
    for (size_t f = 0; f < count; ++f) ckp::Decode(records + f * ckp::kRecordBytes, bits, &out[f]);
    return out;
  }
  EnsureChecked(index);
  const cv::KeyPoint* first = KeypointData() + row_offset_[index];
  return std::vector<cv::KeyPoint>(first, first + count);
}

bool Database::FeaturesChecked(size_t index) const {
  return lazy_ == nullptr || lazy_->checked[index].load(std::memory_order_acquire) != 0;
}

void Database::CheckFeatures(size_t index) const {
  const LazyCheck& lazy = *lazy_;
  const uint64_t first = row_offset_[index];
  const std::string bad =
      FeatureProblem(index, mapped_compact_keypoints_ + first * ckp::kRecordBytes,
                     mapped_descriptors_ + first * static_cast<uint64_t>(descriptor_bytes_));
  if (!bad.empty()) PLACEDB_THROW_CORRUPT(lazy.shown, ": keyframe ", keyframes_[index].id, bad);
  lazy.checked[index].store(1, std::memory_order_release);
}

size_t Database::ReadBlocks(size_t index, bool rows, bool records,
                            std::vector<uint8_t>* buffer) const {
  const uint64_t count = feature_count_[index];
  const uint64_t row_bytes = rows ? count * static_cast<uint64_t>(descriptor_bytes_) : 0;
  const uint64_t record_bytes = records ? count * ckp::kRecordBytes : 0;
  // Descriptor rows first: SURF's floats stay aligned.
  buffer->resize(row_bytes + record_bytes);
  const char* base = mapping_->data();
  if (row_bytes > 0) {
    mapping_->ReadAt(
        static_cast<size_t>(reinterpret_cast<const char*>(mapped_descriptors_) - base) +
            row_offset_[index] * static_cast<uint64_t>(descriptor_bytes_),
        row_bytes, buffer->data());
  }
  if (record_bytes > 0) {
    mapping_->ReadAt(static_cast<size_t>(mapped_compact_keypoints_ - base) +
                         row_offset_[index] * ckp::kRecordBytes,
                     record_bytes, buffer->data() + row_bytes);
  }
  return row_bytes;
}

size_t Database::ReadFeatures(size_t index, bool rows, bool records,
                              std::vector<uint8_t>* buffer) const {
  const bool check = !FeaturesChecked(index);
  const size_t at = ReadBlocks(index, rows || check, records || check, buffer);
  if (check) {
    // The very bytes this use reads are the ones checked.
    const std::string bad =
        FeatureProblem(index, reinterpret_cast<const char*>(buffer->data()) + at, buffer->data());
    if (!bad.empty()) PLACEDB_THROW_CORRUPT(lazy_->shown, ": keyframe ", keyframes_[index].id, bad);
    lazy_->checked[index].store(1, std::memory_order_release);
  }
  return at;
}

std::string Database::FeatureProblem(size_t index, const char* records, const uint8_t* rows) const {
  const LazyCheck& lazy = *lazy_;
  const Keyframe& k = keyframes_[index];
  const size_t count = feature_count_[index];
  if (Checksum64(records, count * ckp::kRecordBytes) != lazy.sums[2 * index])
    return ": its keypoints fail their block checksum (the file is corrupted)";
  if (Checksum64(rows, count * static_cast<size_t>(descriptor_bytes_)) != lazy.sums[2 * index + 1])
    return ": its descriptors fail their block checksum (the file is corrupted)";
  std::vector<cv::KeyPoint> keypoints(count);
  const int bits = ckp::FractionBits(k.stored_size);
  for (size_t f = 0; f < count; ++f) {
    if (!ckp::Decode(records + f * ckp::kRecordBytes, bits, &keypoints[f]))
      return internal::JoinMessage(": keypoint ", f, " has an impossible angle code");
  }
  const std::string bad = CheckKeypoints(keypoints.data(), count, k.stored_size);
  if (!bad.empty()) return " " + bad;
  if (feature_type_ == FeatureType::kSurf) {
    for (size_t f = 0; f < count; ++f) {
      if ((keypoints[f].class_id >= 0) != (f < positive_count_[index]))
        return ": keypoints are not grouped by Laplacian sign";
    }
    if (!AllFinite(reinterpret_cast<const float*>(rows), count * descriptor_bytes_ / 4))
      return " has a SURF descriptor value that is not finite";
  }
  return "";
}

bool Database::CheckSomeInBackground(size_t* next, size_t max_keyframes,
                                     std::vector<uint8_t>* buffer) const {
  if (lazy_ == nullptr || !mapping_ || mapped_compact_keypoints_ == nullptr) return false;
  const LazyCheck& lazy = *lazy_;
  size_t done = 0;
  for (; *next < keyframes_.size() && done < max_keyframes; ++*next) {
    const size_t i = *next;
    if (FeaturesChecked(i)) continue;
    ++done;
    const size_t at = ReadBlocks(i, true, true, buffer);
    // Damage is left unmarked: the first use reads it again and reports it.
    if (FeatureProblem(i, reinterpret_cast<const char*>(buffer->data()) + at, buffer->data())
            .empty())
      lazy.checked[i].store(1, std::memory_order_release);
  }
  return *next < keyframes_.size();
}

void Database::EnsureWholeImageChecked() const {
  if (lazy_ == nullptr || mapped_whole_image_ == nullptr) return;
  LazyCheck& lazy = *lazy_;
  if (lazy.whole_image_checked.load(std::memory_order_acquire)) return;
  const std::lock_guard<std::mutex> lock(lazy.whole_image_mutex);
  if (lazy.whole_image_checked.load(std::memory_order_relaxed)) return;
  const LazyCheck::Section& w = lazy.whole_image;
  if (Checksum64(w.data, w.bytes) != w.checksum)
    PLACEDB_THROW_CORRUPT(lazy.shown,
                          ": whole-image section checksum mismatch (the file is corrupted)");
  if (std::memchr(w.data + kf::kWholeImagePreambleBytes, 0x80,
                  w.bytes - kf::kWholeImagePreambleBytes) != nullptr) {
    PLACEDB_THROW_CORRUPT(lazy.shown,
                          ": the whole-image section holds -128 (values are in [-127, 127])");
  }
  lazy.whole_image_checked.store(true, std::memory_order_release);
}

void Database::VerifyAll() const {
  if (lazy_ == nullptr) return;
  for (const auto& [section, what] : {std::make_pair(&lazy_->keypoints, "keypoint"),
                                      std::make_pair(&lazy_->descriptors, "descriptor")}) {
    if (Checksum64(section->data, section->bytes) != section->checksum) {
      PLACEDB_THROW_CORRUPT(lazy_->shown, ": ", what,
                            " section checksum mismatch (the file is corrupted)");
    }
  }
  // The whole-image section: checked once per session, here or on first use
  // (a subset's rows were checked when they were copied, on open).
  EnsureWholeImageChecked();
  for (size_t i = 0; i < keyframes_.size(); ++i) EnsureChecked(i);
}

DescriptorBlock Database::Descriptors(size_t index, std::vector<uint8_t>* buffer) const {
  if (!reads_features()) return Descriptors(index);
  if (!has_features_) PLACEDB_THROW_INVALID(kNoFeatures);
  ReadFeatures(index, true, false, buffer);
  DescriptorBlock block;
  block.type = feature_type_;
  block.rows = static_cast<int>(feature_count_[index]);
  block.row_bytes = descriptor_bytes_;
  block.data = buffer->data();
  if (feature_type_ == FeatureType::kSurf)
    block.positive_rows = static_cast<int>(positive_count_[index]);
  return block;
}

DescriptorBlock Database::Descriptors(size_t index) const {
  if (!has_features_) PLACEDB_THROW_INVALID(kNoFeatures);
  EnsureChecked(index);
  DescriptorBlock block;
  block.type = feature_type_;
  block.rows = static_cast<int>(feature_count_[index]);
  block.row_bytes = descriptor_bytes_;
  block.data = DescriptorData() + row_offset_[index] * descriptor_bytes_;
  if (feature_type_ == FeatureType::kSurf)
    block.positive_rows = static_cast<int>(positive_count_[index]);
  return block;
}

const int8_t* Database::WholeImageData() const {
  if (whole_image_dims_ == 0) return nullptr;
  if (!has_features_) PLACEDB_THROW_INVALID(kNoFeatures);
  EnsureWholeImageChecked();
  return mapped_whole_image_ != nullptr ? mapped_whole_image_ : whole_image_.data();
}

const int8_t* Database::StandardisingRows(size_t* count) const {
  if (file_whole_image_ != nullptr) {
    *count = file_whole_image_rows_;
    return file_whole_image_;
  }
  *count = whole_image_dims_ > 0 ? keyframes_.size() : 0;
  return WholeImageData();
}

void Database::CopyOnWrite() {
  if (mapped_whole_image_ != nullptr) {
    EnsureWholeImageChecked();
    whole_image_.assign(mapped_whole_image_,
                        mapped_whole_image_ + keyframes_.size() * whole_image_dims_);
    mapped_whole_image_ = nullptr;
  }
  if (!mapping_) return;
  std::vector<cv::KeyPoint> keypoints;
  std::vector<uint8_t> descriptors;
  keypoints.reserve(num_features_);
  descriptors.reserve(num_features_ * descriptor_bytes_);
  std::vector<uint64_t> offsets;
  for (size_t i = 0; i < keyframes_.size(); ++i) {
    offsets.push_back(keypoints.size());
    // Owned keypoints are what a version 3 file keeps (a version 2 file's
    // are quantized here).
    const int bits = ckp::FractionBits(keyframes_[i].stored_size);
    for (const cv::KeyPoint& kp : Keypoints(i)) {
      const std::string why =
          bits < 0 ? "a stored image wider than 65533 px" : ckp::WhyNotEncodable(kp, bits);
      if (!why.empty()) {
        PLACEDB_THROW_INVALID("keyframe ", keyframes_[i].id, " of this version ",
                              file_format_version_, " database has ", why,
                              ", which format version ", kf::kVersion, " cannot keep");
      }
      keypoints.push_back(ckp::Quantized(kp, bits));
    }
    const DescriptorBlock block = Descriptors(i);
    descriptors.insert(descriptors.end(), block.data,
                       block.data + static_cast<size_t>(block.rows) * block.row_bytes);
  }
  keypoints_ = std::move(keypoints);
  descriptors_ = std::move(descriptors);
  row_offset_ = std::move(offsets);
  mapping_.reset();
  mapped_keypoints_ = nullptr;
  mapped_compact_keypoints_ = nullptr;
  mapped_descriptors_ = nullptr;
  lazy_.reset();
}

void Database::AddKeyframe(Keyframe keyframe, const FeatureSet& features) {
  if (!has_features_) {
    PLACEDB_THROW_INVALID("a keyframe table (a database opened without features) cannot grow");
  }
  const std::string reason = CheckKeyframe(keyframe);
  if (!reason.empty()) PLACEDB_THROW_INVALID("keyframe ", keyframe.id, ": ", reason);
  if (features.type != feature_type_) {
    PLACEDB_THROW_INVALID("cannot add ", FeatureTypeName(features.type),
                          " features to a database of ", FeatureTypeName(feature_type_),
                          " features");
  }
  const int rows = features.descriptors.rows;
  if (rows != static_cast<int>(features.keypoints.size())) {
    PLACEDB_THROW_INVALID("keyframe ", keyframe.id, ": one descriptor per keypoint expected (",
                          features.keypoints.size(), " keypoints, ", rows, " descriptor rows)");
  }
  if (rows > 0) {
    const int row_bytes =
        static_cast<int>(features.descriptors.cols * features.descriptors.elemSize());
    if (row_bytes != descriptor_bytes_) {
      PLACEDB_THROW_INVALID("keyframe ", keyframe.id, ": descriptors of ", row_bytes,
                            " bytes, the database's are ", descriptor_bytes_, " bytes");
    }
    if (features.descriptors.channels() != 1 ||
        features.descriptors.depth() != (feature_type_ == FeatureType::kOrb ? CV_8U : CV_32F)) {
      PLACEDB_THROW_INVALID("keyframe ", keyframe.id, ": ", FeatureTypeName(feature_type_),
                            " descriptors must be ",
                            feature_type_ == FeatureType::kOrb ? "CV_8UC1" : "CV_32FC1", " (got ",
                            cv::typeToString(features.descriptors.type()), ")");
    }
  }
  if (whole_image_dims_ > 0) {
    const cv::Mat& w = features.whole_image;
    if (w.empty()) {
      PLACEDB_THROW_INVALID("keyframe ", keyframe.id,
                            " has no whole-image descriptor; the database keeps one of ",
                            whole_image_dims_, " values per keyframe (`whole_image`)");
    }
    if (w.type() != CV_8SC1 || w.rows != 1 || w.cols != whole_image_dims_ || !w.isContinuous()) {
      PLACEDB_THROW_INVALID("keyframe ", keyframe.id, ": its whole-image descriptor is ", w.rows,
                            " x ", w.cols, " ", cv::typeToString(w.type()),
                            ", the database keeps 1 x ", whole_image_dims_, " CV_8SC1 rows");
    }
    if (std::memchr(w.data, 0x80, static_cast<size_t>(whole_image_dims_)) != nullptr) {
      PLACEDB_THROW_INVALID("keyframe ", keyframe.id,
                            ": its whole-image descriptor holds -128 (values are in [-127, 127])");
    }
  }
  const std::string bad_keypoints =
      CheckKeypoints(features.keypoints.data(), features.keypoints.size(), keyframe.stored_size);
  if (!bad_keypoints.empty()) PLACEDB_THROW_INVALID("keyframe ", keyframe.id, " ", bad_keypoints);
  const int bits = ckp::FractionBits(keyframe.stored_size);
  if (bits < 0 && !features.keypoints.empty()) {
    PLACEDB_THROW_INVALID("keyframe ", keyframe.id, ": a stored image of ",
                          keyframe.stored_size.width, " x ", keyframe.stored_size.height,
                          " cannot hold keypoints (a side of at most 65533 px can)");
  }
  for (size_t f = 0; f < features.keypoints.size(); ++f) {
    const std::string why = ckp::WhyNotEncodable(features.keypoints[f], bits);
    if (!why.empty())
      PLACEDB_THROW_INVALID("keyframe ", keyframe.id, " has ", why, " (keypoint ", f, ")");
  }
  if (feature_type_ == FeatureType::kSurf && rows > 0) {
    for (int r = 0; r < rows; ++r) {
      if (!AllFinite(features.descriptors.ptr<float>(r), descriptor_bytes_ / 4)) {
        PLACEDB_THROW_INVALID("keyframe ", keyframe.id,
                              " has a SURF descriptor value that is not finite (row ", r, ")");
      }
    }
  }
  if (IndexOfId(keyframe.id) >= 0) {
    PLACEDB_THROW_INVALID("keyframe id ", keyframe.id, " is already in the database");
  }
  CopyOnWrite();
  // SURF: positive Laplacian first, so the L2 kernel scans one sign's rows
  // without testing each; stable, so the order is otherwise kept.
  std::vector<int> order(rows);
  std::iota(order.begin(), order.end(), 0);
  uint32_t positive = 0;
  if (feature_type_ == FeatureType::kSurf) {
    const auto mid = std::stable_partition(
        order.begin(), order.end(), [&](int r) { return features.keypoints[r].class_id >= 0; });
    positive = static_cast<uint32_t>(mid - order.begin());
  }
  row_offset_.push_back(keypoints_.size());
  feature_count_.push_back(static_cast<uint32_t>(rows));
  positive_count_.push_back(positive);
  for (const int r : order) {
    keypoints_.push_back(ckp::Quantized(features.keypoints[r], bits));
    const uint8_t* row = features.descriptors.ptr<uint8_t>(r);
    descriptors_.insert(descriptors_.end(), row, row + descriptor_bytes_);
  }
  num_features_ += static_cast<size_t>(rows);
  if (whole_image_dims_ > 0) {
    const int8_t* w = features.whole_image.ptr<int8_t>();
    whole_image_.insert(whole_image_.end(), w, w + whole_image_dims_);
  }
  index_of_id_.emplace(keyframe.id, static_cast<int>(keyframes_.size()));
  keyframes_.push_back(std::move(keyframe));
  keyframes_in_file_ = keyframes_.size();
}

bool Database::HasRoomFor(size_t keyframes, size_t features) const {
  if (mapping_) return false;
  return keyframes_.capacity() - keyframes_.size() >= keyframes &&
         row_offset_.capacity() - row_offset_.size() >= keyframes &&
         feature_count_.capacity() - feature_count_.size() >= keyframes &&
         positive_count_.capacity() - positive_count_.size() >= keyframes &&
         keypoints_.capacity() - keypoints_.size() >= features &&
         descriptors_.capacity() - descriptors_.size() >= features * descriptor_bytes_ &&
         whole_image_.capacity() - whole_image_.size() >= keyframes * whole_image_dims_ &&
         static_cast<double>(index_of_id_.size() + keyframes) <=
             static_cast<double>(index_of_id_.bucket_count()) * index_of_id_.max_load_factor();
}

void Database::Reserve(size_t keyframes, size_t features) {
  CopyOnWrite();
  keyframes_.reserve(keyframes);
  row_offset_.reserve(keyframes);
  feature_count_.reserve(keyframes);
  positive_count_.reserve(keyframes);
  index_of_id_.reserve(keyframes);
  keypoints_.reserve(features);
  descriptors_.reserve(features * descriptor_bytes_);
  whole_image_.reserve(keyframes * whole_image_dims_);
}

FeatureSet Database::Features(size_t index) const {
  FeatureSet f;
  f.type = feature_type_;
  f.keypoints = Keypoints(index);
  const DescriptorBlock block = Descriptors(index);
  const int cols = feature_type_ == FeatureType::kOrb ? descriptor_bytes_ : descriptor_bytes_ / 4;
  const int type = feature_type_ == FeatureType::kOrb ? CV_8U : CV_32F;
  cv::Mat(block.rows, cols, type, const_cast<uint8_t*>(block.data)).copyTo(f.descriptors);
  if (f.descriptors.empty()) f.descriptors = cv::Mat(0, cols, type);
  if (whole_image_dims_ > 0) {
    cv::Mat(1, whole_image_dims_, CV_8S, const_cast<int8_t*>(WholeImage(index)))
        .copyTo(f.whole_image);
  }
  return f;
}

Database Database::Compacted(const std::vector<char>& keep) const {
  if (keep.size() != keyframes_.size()) {
    PLACEDB_THROW_INVALID("compacting needs one keep flag per keyframe (", keep.size(), " for ",
                          keyframes_.size(), " keyframes)");
  }
  Database out(feature_type_, descriptor_bytes_, whole_image_dims_);
  size_t kept = 0, rows = 0;
  for (size_t i = 0; i < keep.size(); ++i) {
    if (!keep[i]) continue;
    ++kept;
    rows += feature_count_[i];
  }
  out.Reserve(kept, rows);
  for (size_t i = 0; i < keep.size(); ++i) {
    if (keep[i]) out.AddKeyframe(keyframes_[i], Features(i));
  }
  out.info_ = info_;
  return out;
}

// ---- writing ------------------------------------------------------------------

std::string Database::KeyframesFileName(uint64_t checksum) {
  return "keyframes." + ChecksumHex(checksum) + ".bin";
}

bool Database::IsKeyframesFileName(const std::string& name) {
  if (name == "keyframes.bin") return true;
  if (name.size() != 10 + 16 + 4 || name.compare(0, 10, "keyframes.") != 0 ||
      name.compare(26, 4, ".bin") != 0) {
    return false;
  }
  return std::all_of(name.begin() + 10, name.begin() + 26,
                     [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); });
}

Database::SaveResult Database::Save(const std::string& dir) const {
  if (!has_features_) {
    PLACEDB_THROW_INVALID("a keyframe table (a database opened without features) cannot be saved");
  }
  if (!HostIsLittleEndian()) PLACEDB_THROW_IO("placedb databases need a little-endian host");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) PLACEDB_THROW_NOT_FOUND("database folder not found: ", dir);
  if (!subset_.all() && fs::exists(fs::path(dir) / kManifestFile, ec)) {
    PLACEDB_THROW_INVALID("cannot save ", subset_.Describe(), " into ", dir,
                          ": it holds a database, which the subset would replace (save a subset "
                          "into a new folder)");
  }
  // The whole-image section only with the channel: files without it are
  // what earlier placedb versions read.
  const uint32_t num_sections = whole_image_dims_ > 0 ? 7 : 6;
  char header[kf::kHeaderBytes + 7 * kf::kSectionEntryBytes] = {};
  // Every keypoint must fit its compact record (owned keypoints do: they
  // are quantized when added; a version 2 file's may not).
  for (size_t i = 0; i < keyframes_.size(); ++i) {
    const int bits = ckp::FractionBits(keyframes_[i].stored_size);
    for (const cv::KeyPoint& kp : Keypoints(i)) {
      const std::string why =
          bits < 0 ? "a stored image wider than 65533 px" : ckp::WhyNotEncodable(kp, bits);
      if (!why.empty()) {
        PLACEDB_THROW_INVALID("keyframe ", keyframes_[i].id, " has ", why,
                              ", which format version ", kf::kVersion, " cannot keep");
      }
    }
  }

  // Written to a temporary file, committed under its content name.
  AtomicFileWriter out((fs::path(dir) / "keyframes.bin").string());
  out.Write(header, kf::kHeaderBytes + num_sections * kf::kSectionEntryBytes);  // filled in last
  out.Align(kf::kSectionAlignment);
  struct Written {
    uint64_t offset, bytes, checksum;
  };
  auto section = [&](const auto& write_body) {
    out.Align(kf::kSectionAlignment);
    Checksum64Stream sum;
    const uint64_t begin = out.position();
    write_body([&](const void* data, size_t size) {
      out.Write(data, size);
      sum.Update(data, size);
    });
    return Written{begin, out.position() - begin, sum.Digest()};
  };

  // Keyframes, then the string table they point into.
  uint64_t feature_offset = 0, string_offset = 0;
  const Written keyframes = section([&](auto put) {
    char r[kf::kKeyframeRecordBytes];
    for (size_t i = 0; i < keyframes_.size(); ++i) {
      const Keyframe& k = keyframes_[i];
      std::memset(r, 0, sizeof(r));
      SetField<int32_t>(r, rec::kId, k.id);
      SetField<int32_t>(r, rec::kCropChannel, k.crop_channel);
      SetField<int32_t>(r, rec::kCropX, k.crop.x);
      SetField<int32_t>(r, rec::kCropY, k.crop.y);
      SetField<int32_t>(r, rec::kCropW, k.crop.width);
      SetField<int32_t>(r, rec::kCropH, k.crop.height);
      SetField<int32_t>(r, rec::kOrigW, k.original_size.width);
      SetField<int32_t>(r, rec::kOrigH, k.original_size.height);
      SetField<int32_t>(r, rec::kStoredW, k.stored_size.width);
      SetField<int32_t>(r, rec::kStoredH, k.stored_size.height);
      SetField<double>(r, rec::kTimestamp, k.timestamp);
      SetField<double>(r, rec::kScale, k.scale);
      SetField<uint32_t>(r, rec::kHasPose, k.pose ? 1u : 0u);
      SetField<uint32_t>(r, rec::kPositive, positive_count_[i]);
      const Pose pose = k.pose.value_or(Pose());
      for (int c = 0; c < 3; ++c) SetField<double>(r, rec::kTx + 8 * c, pose.translation[c]);
      const Eigen::Vector4d q = pose.rotation.coeffs();  // x, y, z, w
      for (int c = 0; c < 4; ++c) SetField<double>(r, rec::kQx + 8 * c, q[c]);
      SetField<uint64_t>(r, rec::kFeatureOffset, feature_offset);
      SetField<uint32_t>(r, rec::kFeatureCount, feature_count_[i]);
      SetField<uint32_t>(r, rec::kSourceLen, static_cast<uint32_t>(k.source.size()));
      SetField<uint64_t>(r, rec::kStringOffset, string_offset);
      SetField<uint32_t>(r, rec::kImageLen, static_cast<uint32_t>(k.image_file.size()));
      put(r, sizeof(r));
      feature_offset += feature_count_[i];
      string_offset += k.source.size() + k.image_file.size();
    }
  });
  const Written strings = section([&](auto put) {
    for (const Keyframe& k : keyframes_) {
      put(k.source.data(), k.source.size());
      put(k.image_file.data(), k.image_file.size());
    }
  });
  // The small sections first: the descriptors stay last.
  const Written source_hashes = section([&](auto put) {
    for (const Keyframe& k : keyframes_) {
      char h[8];
      SetField<uint64_t>(h, 0, k.source_hash);
      put(h, sizeof(h));
    }
  });
  Written whole_image{0, 0, 0};
  if (whole_image_dims_ > 0) {
    whole_image = section([&](auto put) {
      char preamble[kf::kWholeImagePreambleBytes] = {};
      SetField<uint32_t>(preamble, 0, static_cast<uint32_t>(whole_image_dims_));
      put(preamble, sizeof(preamble));
      // An empty database's rows may be a null pointer (no memcpy from it).
      if (!keyframes_.empty()) put(WholeImageData(), keyframes_.size() * whole_image_dims_);
    });
  }
  // Each keyframe's two block checksums, taken as its records are written.
  std::vector<uint64_t> block_sums(2 * keyframes_.size());
  const Written keypoints = section([&](auto put) {
    char preamble[kf::kCompactKeypointPreambleBytes] = {};
    SetField<uint32_t>(preamble, 0, static_cast<uint32_t>(ckp::kRecordBytes));
    SetField<uint32_t>(preamble, 4, ckp::kPositionScheme);
    put(preamble, sizeof(preamble));
    std::vector<char> records;
    for (size_t i = 0; i < keyframes_.size(); ++i) {
      const std::vector<cv::KeyPoint> kp = Keypoints(i);
      records.resize(kp.size() * ckp::kRecordBytes);
      const int bits = ckp::FractionBits(keyframes_[i].stored_size);
      for (size_t f = 0; f < kp.size(); ++f)
        ckp::Encode(kp[f], bits, records.data() + f * ckp::kRecordBytes);
      block_sums[2 * i] = Checksum64(records.data(), records.size());
      put(records.data(), records.size());
    }
  });
  const Written descriptors = section([&](auto put) {
    for (size_t i = 0; i < keyframes_.size(); ++i) {
      const DescriptorBlock b = Descriptors(i);
      const size_t bytes = static_cast<size_t>(b.rows) * b.row_bytes;
      block_sums[2 * i + 1] = Checksum64(b.data, bytes);
      put(b.data, bytes);
    }
  });
  const Written feature_blocks = section([&](auto put) {
    for (const uint64_t sum : block_sums) {
      char h[8];
      SetField<uint64_t>(h, 0, sum);
      put(h, sizeof(h));
    }
  });
  const uint64_t file_bytes = out.position();

  std::memcpy(header, kf::kMagic, sizeof(kf::kMagic));
  SetField<uint32_t>(header, 8, kf::kVersion);
  SetField<uint32_t>(header, 12, kf::kHeaderBytes);
  SetField<uint32_t>(header, 16, static_cast<uint32_t>(feature_type_));
  SetField<uint32_t>(header, 20, static_cast<uint32_t>(descriptor_bytes_));
  SetField<uint32_t>(header, 24, num_sections);
  SetField<uint64_t>(header, 32, keyframes_.size());
  SetField<uint64_t>(header, 40, num_features_);
  SetField<uint64_t>(header, 48, file_bytes);
  const std::pair<uint32_t, Written> table[] = {
      {kf::kKeyframes, keyframes},          {kf::kStrings, strings},
      {kf::kCompactKeypoints, keypoints},   {kf::kDescriptors, descriptors},
      {kf::kFeatureBlocks, feature_blocks}, {kf::kSourceHashes, source_hashes},
      {kf::kWholeImage, whole_image}};
  for (uint32_t s = 0; s < num_sections; ++s) {
    char* e = header + kf::kHeaderBytes + s * kf::kSectionEntryBytes;
    SetField<uint32_t>(e, 0, table[s].first);
    SetField<uint64_t>(e, 8, table[s].second.offset);
    SetField<uint64_t>(e, 16, table[s].second.bytes);
    SetField<uint64_t>(e, 24, table[s].second.checksum);
  }
  const uint64_t checksum = HeaderChecksum(header, num_sections);
  SetField<uint64_t>(header, kf::kChecksumOffset, checksum);
  out.WriteAt(0, header, kf::kHeaderBytes + num_sections * kf::kSectionEntryBytes);

  // The new generation under its own name, then the manifest that names it,
  // then the old generation goes: a crash leaves one complete pair.
  SaveResult result;
  result.keyframes_file = KeyframesFileName(checksum);
  result.keyframes_bytes = file_bytes;
  out.CommitAs((fs::path(dir) / result.keyframes_file).string());  // durable

  nlohmann::json manifest = info_;
  manifest["format"] = "placedb-database";
  manifest["format_version"] = kDatabaseFormatVersion;
  manifest["feature_type"] = FeatureTypeName(feature_type_);
  manifest["descriptor_bytes"] = descriptor_bytes_;
  if (whole_image_dims_ > 0) {
    manifest["whole_image_dims"] = whole_image_dims_;
  } else {
    manifest.erase("whole_image_dims");
  }
  manifest["counts"]["keyframes"] = keyframes_.size();
  manifest["counts"]["features"] = num_features_;
  manifest["files"] = {{"keyframes", result.keyframes_file},
                       {"keyframes_bytes", file_bytes},
                       {"keyframes_checksum", ChecksumHex(checksum)}};
  if (!subset_.all()) manifest["subset_of"] = subset_.Describe();
  WriteFileAtomic((fs::path(dir) / kManifestFile).string(), DumpJson(manifest, 2) + "\n");

  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (IsKeyframesFileName(name) && name != result.keyframes_file) fs::remove(entry.path(), ec);
  }
  return result;
}

uint64_t keyframe_file::Reseal(std::string* bytes, bool fix_size) {
  if (bytes->size() < kHeaderBytes) return 0;
  char* b = bytes->data();
  const uint32_t num_sections = std::min(Field<uint32_t>(b, 24), kMaxSections);
  if (kHeaderBytes + static_cast<size_t>(num_sections) * kSectionEntryBytes > bytes->size())
    return 0;
  if (fix_size) SetField<uint64_t>(b, 48, bytes->size());
  const uint64_t size = bytes->size();
  // Version 3: the block checksums of the keyframes whose records, keypoint
  // and descriptor ranges lie inside their sections.
  uint64_t offsets[kLastKind + 1] = {}, sizes[kLastKind + 1] = {};
  for (uint32_t s = 0; s < num_sections; ++s) {
    const char* e = b + kHeaderBytes + s * kSectionEntryBytes;
    const uint32_t kind = Field<uint32_t>(e, 0);
    const uint64_t offset = Field<uint64_t>(e, 8), bytes_in = Field<uint64_t>(e, 16);
    if (kind <= kLastKind && offset <= size && bytes_in <= size - offset) {
      offsets[kind] = offset;
      sizes[kind] = bytes_in;
    }
  }
  const uint64_t row_bytes = Field<uint32_t>(b, 20);
  if (Field<uint32_t>(b, 8) == 3 && sizes[kKeyframes] > 0 && sizes[kFeatureBlocks] > 0 &&
      sizes[kCompactKeypoints] >= kCompactKeypointPreambleBytes && row_bytes > 0) {
    const uint64_t records = std::min(sizes[kKeyframes] / kKeyframeRecordBytes,
                                      sizes[kFeatureBlocks] / kFeatureBlockEntryBytes);
    const uint64_t keypoint_rows =
        (sizes[kCompactKeypoints] - kCompactKeypointPreambleBytes) / compact_keypoint::kRecordBytes;
    const uint64_t descriptor_rows = sizes[kDescriptors] / row_bytes;
    for (uint64_t i = 0; i < records; ++i) {
      const char* r = b + offsets[kKeyframes] + i * kKeyframeRecordBytes;
      const uint64_t first = Field<uint64_t>(r, rec::kFeatureOffset);
      const uint64_t count = Field<uint32_t>(r, rec::kFeatureCount);
      if (first > keypoint_rows || count > keypoint_rows - first || first > descriptor_rows ||
          count > descriptor_rows - first) {
        continue;
      }
      char* entry = b + offsets[kFeatureBlocks] + i * kFeatureBlockEntryBytes;
      SetField<uint64_t>(entry, 0,
                         Checksum64(b + offsets[kCompactKeypoints] + kCompactKeypointPreambleBytes +
                                        first * compact_keypoint::kRecordBytes,
                                    count * compact_keypoint::kRecordBytes));
      SetField<uint64_t>(
          entry, 8, Checksum64(b + offsets[kDescriptors] + first * row_bytes, count * row_bytes));
    }
  }
  for (uint32_t s = 0; s < num_sections; ++s) {
    char* e = b + kHeaderBytes + s * kSectionEntryBytes;
    const uint64_t offset = Field<uint64_t>(e, 8), size = Field<uint64_t>(e, 16);
    if (offset <= bytes->size() && size <= bytes->size() - offset) {
      SetField<uint64_t>(e, 24, Checksum64(b + offset, size));
    }
  }
  const uint64_t checksum = HeaderChecksum(b, num_sections);
  SetField<uint64_t>(b, kChecksumOffset, checksum);
  return checksum;
}

// ---- reading ------------------------------------------------------------------

void Database::DecodeKeyframeFile(std::shared_ptr<const MappedFile> file, const std::string& shown,
                                  const LoadOptions& options) {
  const char* b = file->data();
  const size_t size = file->size();
  auto fail = [&](const auto&... what) { PLACEDB_THROW_CORRUPT(shown, ": ", what...); };
  // A file cut inside the magic (a prefix of it, or empty) is truncated, not
  // a different kind of file.
  if (size < sizeof(kf::kMagic) && (size == 0 || std::memcmp(b, kf::kMagic, size) == 0))
    fail("file is truncated (", size, " bytes)");
  if (size < sizeof(kf::kMagic) || std::memcmp(b, kf::kMagic, sizeof(kf::kMagic)) != 0)
    fail("not a placedb keyframe file (wrong magic)");
  if (size < kf::kHeaderBytes) fail("file is truncated (", size, " bytes)");
  const uint32_t version = Field<uint32_t>(b, 8);
  if (version < kf::kOldestVersion || version > kf::kVersion)
    fail("format version ", version, " is not supported (this placedb reads versions ",
         kf::kOldestVersion, " to ", kf::kVersion, ")");
  const bool compact = version >= 3;
  if (Field<uint32_t>(b, 12) != kf::kHeaderBytes) fail("bad header size ", Field<uint32_t>(b, 12));
  const uint64_t file_bytes = Field<uint64_t>(b, 48);
  if (file_bytes != size) {
    fail(size < file_bytes ? "file is truncated" : "file has unexpected trailing bytes", " (", size,
         " bytes, the header says ", file_bytes, ")");
  }
  const uint32_t num_sections = Field<uint32_t>(b, 24);
  if (num_sections < kf::kMinSections || num_sections > kf::kMaxSections)
    fail("bad section count ", num_sections);
  const size_t table_end = kf::kHeaderBytes + num_sections * kf::kSectionEntryBytes;
  if (table_end > size) fail("file is truncated inside the section table");
  if (HeaderChecksum(b, num_sections) != Field<uint64_t>(b, kf::kChecksumOffset))
    fail("header checksum mismatch (the file is corrupted)");
  if (Field<uint32_t>(b, 28) != 0) fail("reserved header field is not 0");

  const uint32_t type = Field<uint32_t>(b, 16);
  if (type != static_cast<uint32_t>(FeatureType::kOrb) &&
      type != static_cast<uint32_t>(FeatureType::kSurf)) {
    fail("unknown feature type ", type);
  }
  feature_type_ = static_cast<FeatureType>(type);
  const uint32_t row_bytes = Field<uint32_t>(b, 20);
  const bool width_ok =
      feature_type_ == FeatureType::kOrb ? row_bytes == 32 : (row_bytes == 256 || row_bytes == 512);
  if (!width_ok)
    fail(FeatureTypeName(feature_type_), " descriptors cannot be ", row_bytes, " bytes wide");
  descriptor_bytes_ = static_cast<int>(row_bytes);
  const uint64_t num_keyframes = Field<uint64_t>(b, 32);
  const uint64_t num_features = Field<uint64_t>(b, 40);
  // Bounds that keep every product below below 2^64.
  if (num_keyframes > size / kf::kKeyframeRecordBytes)
    fail("keyframe count ", num_keyframes, " exceeds the file");
  const uint64_t keypoint_bytes = compact ? ckp::kRecordBytes : kf::kKeypointRecordBytes;
  if (num_features > size / keypoint_bytes || num_features > size / row_bytes)
    fail("feature count ", num_features, " exceeds the file");

  // The section table: known kinds once each, aligned, inside the file, not
  // overlapping each other or the table.
  struct Section {
    uint64_t offset = 0, bytes = 0, checksum = 0;
    bool present = false;
  };
  Section sections[kf::kLastKind + 1];
  std::vector<std::pair<uint64_t, uint64_t>> extents;
  for (uint32_t s = 0; s < num_sections; ++s) {
    const char* e = b + kf::kHeaderBytes + s * kf::kSectionEntryBytes;
    const uint32_t kind = Field<uint32_t>(e, 0);
    const uint64_t offset = Field<uint64_t>(e, 8), bytes = Field<uint64_t>(e, 16);
    if (Field<uint32_t>(e, 4) != 0) fail("section ", s, ": reserved field is not 0");
    if (offset % kf::kSectionAlignment != 0) fail("section ", s, " is not aligned");
    if (offset < table_end || offset > size || bytes > size - offset)
      fail("section ", s, " (offset ", offset, ", ", bytes, " bytes) lies outside the file");
    extents.emplace_back(offset, bytes);
    if (kind >= kf::kKeyframes && kind <= kf::kLastKind) {
      if (sections[kind].present) fail("section kind ", kind, " appears twice");
      sections[kind] = {offset, bytes, Field<uint64_t>(e, 24), true};
    }
  }
  std::sort(extents.begin(), extents.end());
  for (size_t i = 1; i < extents.size(); ++i) {
    if (extents[i].first < extents[i - 1].first + extents[i - 1].second) fail("sections overlap");
  }
  // Each version's keypoints, and only its own.
  const uint32_t keypoint_kind = compact ? kf::kCompactKeypoints : kf::kKeypoints;
  for (const uint32_t kind : {uint32_t{kf::kKeyframes}, uint32_t{kf::kStrings}, keypoint_kind,
                              uint32_t{kf::kDescriptors}}) {
    if (!sections[kind].present) fail("section kind ", kind, " is missing");
  }
  if (compact && !sections[kf::kFeatureBlocks].present)
    fail("section kind ", kf::kFeatureBlocks, " is missing");
  for (const uint32_t kind :
       compact ? std::vector<uint32_t>{kf::kKeypoints}
               : std::vector<uint32_t>{kf::kCompactKeypoints, kf::kFeatureBlocks}) {
    if (sections[kind].present)
      fail("section kind ", kind, " does not belong in a version ", version, " file");
  }
  const Section& keyframes = sections[kf::kKeyframes];
  const Section& strings = sections[kf::kStrings];
  const Section& keypoints = sections[keypoint_kind];
  const Section& descriptors = sections[kf::kDescriptors];
  const Section& feature_blocks = sections[kf::kFeatureBlocks];
  if (keyframes.bytes != num_keyframes * kf::kKeyframeRecordBytes)
    fail("the keyframe section's size does not match ", num_keyframes, " keyframes");
  const uint64_t keypoint_preamble = compact ? kf::kCompactKeypointPreambleBytes : 0;
  if (keypoints.bytes != keypoint_preamble + num_features * keypoint_bytes)
    fail("the keypoint section's size does not match ", num_features, " features");
  if (compact) {
    const char* preamble = b + keypoints.offset;
    if (Field<uint32_t>(preamble, 0) != ckp::kRecordBytes ||
        Field<uint32_t>(preamble, 4) != ckp::kPositionScheme) {
      fail("compact keypoints of ", Field<uint32_t>(preamble, 0), " bytes with position scheme ",
           Field<uint32_t>(preamble, 4), " (this placedb reads ", ckp::kRecordBytes,
           " bytes, scheme ", ckp::kPositionScheme, ")");
    }
    for (size_t at = 8; at < kf::kCompactKeypointPreambleBytes; ++at) {
      if (preamble[at] != 0) fail("the compact keypoint section's reserved bytes are not 0");
    }
    if (feature_blocks.bytes != num_keyframes * kf::kFeatureBlockEntryBytes)
      fail("the feature block section's size does not match ", num_keyframes, " keyframes");
  }
  if (descriptors.bytes != num_features * row_bytes)
    fail("the descriptor section's size does not match ", num_features, " features");
  // Optional (files of earlier versions lack it: hashes not recorded).
  const Section& source_hashes = sections[kf::kSourceHashes];
  if (source_hashes.present && source_hashes.bytes != num_keyframes * 8)
    fail("the source hash section's size does not match ", num_keyframes, " keyframes");
  // Optional: the whole-image channel, its preamble and K rows.
  const Section& whole_image = sections[kf::kWholeImage];
  uint32_t whole_image_dims = 0;
  if (whole_image.present) {
    if (whole_image.bytes < kf::kWholeImagePreambleBytes)
      fail("the whole-image section is shorter than its preamble");
    const char* preamble = b + whole_image.offset;
    whole_image_dims = Field<uint32_t>(preamble, 0);
    if (whole_image_dims < kf::kMinWholeImageDims || whole_image_dims > kf::kMaxWholeImageDims)
      fail("whole-image rows of ", whole_image_dims, " values (expected [", kf::kMinWholeImageDims,
           ", ", kf::kMaxWholeImageDims, "])");
    for (size_t at = 4; at < kf::kWholeImagePreambleBytes; ++at) {
      if (preamble[at] != 0) fail("the whole-image section's reserved bytes are not 0");
    }
    // num_keyframes <= size / 152: the product stays far below 2^64.
    if (whole_image.bytes - kf::kWholeImagePreambleBytes != num_keyframes * whole_image_dims)
      fail("the whole-image section's size does not match ", num_keyframes, " keyframes of ",
           whole_image_dims, " values");
  }
  const bool with_features = options.contents == LoadContents::kAll;
  auto verify = [&](const Section& s, const char* what) {
    if (Checksum64(b + s.offset, s.bytes) != s.checksum)
      fail(what, " checksum mismatch (the file is corrupted)");
  };
  // The small sections the keyframe records read; the large ones (hundreds
  // of MB at 10 000 keyframes) below, once the records say where each
  // keyframe's features lie.
  verify(keyframes, "keyframe section");
  verify(strings, "string section");
  if (source_hashes.present) verify(source_hashes, "source hash section");
  if (compact && with_features) verify(feature_blocks, "feature block section");
  const char* whole_image_rows = b + whole_image.offset + kf::kWholeImagePreambleBytes;
  const auto verify_whole_image = [&] {
    verify(whole_image, "whole-image section");
    if (std::memchr(whole_image_rows, 0x80, whole_image.bytes - kf::kWholeImagePreambleBytes))
      fail("the whole-image section holds -128 (values are in [-127, 127])");
  };
  // Version 3 checks the rows used in place on first use (below).
  if (whole_image.present && with_features && !compact) verify_whole_image();

  // Keyframe records: every value checked; ranges back to back.
  std::vector<Keyframe> all(num_keyframes);
  std::vector<uint64_t> offsets(num_keyframes);
  std::vector<uint32_t> counts(num_keyframes), positives(num_keyframes);
  std::vector<int32_t> ids(num_keyframes);
  uint64_t expected_offset = 0;
  std::unordered_set<int32_t> seen;
  seen.reserve(num_keyframes);
  for (uint64_t i = 0; i < num_keyframes; ++i) {
    const char* r = b + keyframes.offset + i * kf::kKeyframeRecordBytes;
    Keyframe& k = all[i];
    k.id = Field<int32_t>(r, rec::kId);
    k.crop_channel = Field<int32_t>(r, rec::kCropChannel);
    k.crop = cv::Rect(Field<int32_t>(r, rec::kCropX), Field<int32_t>(r, rec::kCropY),
                      Field<int32_t>(r, rec::kCropW), Field<int32_t>(r, rec::kCropH));
    k.original_size = cv::Size(Field<int32_t>(r, rec::kOrigW), Field<int32_t>(r, rec::kOrigH));
    k.stored_size = cv::Size(Field<int32_t>(r, rec::kStoredW), Field<int32_t>(r, rec::kStoredH));
    k.timestamp = Field<double>(r, rec::kTimestamp);
    k.scale = Field<double>(r, rec::kScale);
    const uint32_t has_pose = Field<uint32_t>(r, rec::kHasPose);
    if (has_pose > 1) fail("keyframe record ", i, ": bad pose flag ", has_pose);
    if (has_pose) {
      Pose pose;
      for (int c = 0; c < 3; ++c) pose.translation[c] = Field<double>(r, rec::kTx + 8 * c);
      pose.rotation =
          Eigen::Quaterniond(Field<double>(r, rec::kQx + 24), Field<double>(r, rec::kQx),
                             Field<double>(r, rec::kQx + 8), Field<double>(r, rec::kQx + 16));
      k.pose = pose;
    }
    if (!seen.insert(k.id).second) fail("keyframe id ", k.id, " appears twice");
    ids[i] = k.id;
    offsets[i] = Field<uint64_t>(r, rec::kFeatureOffset);
    counts[i] = Field<uint32_t>(r, rec::kFeatureCount);
    positives[i] = Field<uint32_t>(r, rec::kPositive);
    if (offsets[i] != expected_offset || counts[i] > num_features - expected_offset)
      fail("keyframe ", k.id, " refers to features outside its range");
    expected_offset += counts[i];
    if (positives[i] > counts[i] || (feature_type_ == FeatureType::kOrb && positives[i] != 0))
      fail("keyframe ", k.id, ": bad Laplacian split ", positives[i], " of ", counts[i]);
    const uint64_t string_offset = Field<uint64_t>(r, rec::kStringOffset);
    const uint64_t source_len = Field<uint32_t>(r, rec::kSourceLen);
    const uint64_t image_len = Field<uint32_t>(r, rec::kImageLen);
    if (source_len > kMaxPathBytes || image_len > kMaxPathBytes || string_offset > strings.bytes ||
        source_len + image_len > strings.bytes - string_offset) {
      fail("keyframe ", k.id, " refers to strings outside the string section");
    }
    if (Field<uint32_t>(r, rec::kReserved) != 0)
      fail("keyframe record ", i, ": reserved field is not 0");
    const char* text = b + strings.offset + string_offset;
    k.source.assign(text, source_len);
    k.image_file.assign(text + source_len, image_len);
    if (source_hashes.present)
      k.source_hash = Field<uint64_t>(b + source_hashes.offset, static_cast<size_t>(8 * i));
    const std::string reason = CheckKeyframe(k);
    if (!reason.empty()) fail("keyframe record ", i, " (id ", k.id, "): ", reason);
    if (compact && counts[i] > 0 && ckp::FractionBits(k.stored_size) < 0)
      fail("keyframe record ", i, " (id ", k.id,
           "): a stored image wider than 65533 px holds keypoints");
  }
  if (expected_offset != num_features)
    fail("the keyframes own ", expected_offset, " features but the file holds ", num_features);

  // The subset to keep, and its keypoints checked in place.
  const std::vector<size_t> keep = SelectKeyframes(options.subset, num_keyframes, ids);
  const auto* file_keypoints =
      reinterpret_cast<const cv::KeyPoint*>(b + keypoints.offset);  // 64-byte aligned
  // Version 2: every byte checked now. Version 3: on first use (LazyCheck).
  if (with_features && !compact) {
    std::vector<char> kept(num_keyframes, 0);
    for (const size_t i : keep) kept[i] = 1;
    // What is wrong with the first kept keyframe whose keypoints are bad.
    std::string bad_keypoints;
    const auto check_keypoints = [&](size_t i) {
      const std::string bad =
          CheckKeypoints(file_keypoints + offsets[i], counts[i], all[i].stored_size);
      if (!bad.empty()) {
        bad_keypoints = "keyframe " + std::to_string(all[i].id) + " " + bad;
        return;
      }
      for (uint32_t f = 0; f < counts[i]; ++f) {
        const cv::KeyPoint& kp = file_keypoints[offsets[i] + f];
        if (feature_type_ == FeatureType::kSurf && (kp.class_id >= 0) != (f < positives[i])) {
          bad_keypoints = "keyframe " + std::to_string(all[i].id) +
                          ": keypoints are not grouped by Laplacian sign";
          return;
        }
      }
    };
    // One pass over the keypoints (their ranges lie back to back, in
    // keyframe order): a stretch of about 256 KB is hashed, then its kept
    // keyframes' keypoints are checked while it is in cache. The
    // descriptors are hashed at the same time, on another thread. A
    // checksum mismatch is reported before what the keypoints show.
    const auto hash_and_check_keypoints = [&] {
      Checksum64Stream sum;
      constexpr uint64_t kStretch = (256 << 10) / kf::kKeypointRecordBytes;
      for (uint64_t i = 0; i < num_keyframes;) {
        uint64_t j = i + 1;
        while (j < num_keyframes && offsets[j] + counts[j] - offsets[i] <= kStretch) ++j;
        const uint64_t first = offsets[i], last = offsets[j - 1] + counts[j - 1];
        sum.Update(b + keypoints.offset + first * kf::kKeypointRecordBytes,
                   static_cast<size_t>((last - first) * kf::kKeypointRecordBytes));
        for (uint64_t k = i; k < j && bad_keypoints.empty(); ++k) {
          if (kept[k]) check_keypoints(k);
        }
        i = j;
      }
      if (sum.Digest() != keypoints.checksum)
        fail("keypoint section checksum mismatch (the file is corrupted)");
    };
    // The descriptors the same way: SURF rows of kept keyframes must be
    // finite, checked while their stretch is in cache.
    std::string bad_descriptors;
    const auto hash_and_check_descriptors = [&] {
      if (feature_type_ != FeatureType::kSurf) {
        verify(descriptors, "descriptor section");
        return;
      }
      Checksum64Stream sum;
      const uint64_t stretch = std::max<uint64_t>(1, (256 << 10) / row_bytes);
      const char* base = b + descriptors.offset;
      for (uint64_t i = 0; i < num_keyframes;) {
        uint64_t j = i + 1;
        while (j < num_keyframes && offsets[j] + counts[j] - offsets[i] <= stretch) ++j;
        const uint64_t first = offsets[i], last = offsets[j - 1] + counts[j - 1];
        sum.Update(base + first * row_bytes, static_cast<size_t>((last - first) * row_bytes));
        for (uint64_t k = i; k < j && bad_descriptors.empty(); ++k) {
          if (kept[k] && !AllFinite(reinterpret_cast<const float*>(base + offsets[k] * row_bytes),
                                    static_cast<size_t>(counts[k]) * row_bytes / 4)) {
            bad_descriptors = "keyframe " + std::to_string(all[k].id) +
                              " has a SURF descriptor value that is not finite";
          }
        }
        i = j;
      }
      if (sum.Digest() != descriptors.checksum)
        fail("descriptor section checksum mismatch (the file is corrupted)");
    };
    RunTogether({hash_and_check_keypoints, hash_and_check_descriptors});
    if (!bad_keypoints.empty()) fail(bad_keypoints);
    if (!bad_descriptors.empty()) fail(bad_descriptors);
  }
  whole_image_dims_ = static_cast<int>(whole_image_dims);
  if (whole_image.present && with_features) {
    bool in_place = keep.size() == num_keyframes;
    for (size_t j = 0; in_place && j < keep.size(); ++j) in_place = keep[j] == j;
    if (in_place) {
      mapped_whole_image_ = reinterpret_cast<const int8_t*>(whole_image_rows);
    } else {
      if (compact) verify_whole_image();  // copied now, so checked now
      file_whole_image_ = reinterpret_cast<const int8_t*>(whole_image_rows);
      file_whole_image_rows_ = num_keyframes;
      whole_image_.reserve(keep.size() * whole_image_dims);
      for (const size_t i : keep) {
        const auto* row = reinterpret_cast<const int8_t*>(whole_image_rows) + i * whole_image_dims;
        whole_image_.insert(whole_image_.end(), row, row + whole_image_dims);
      }
    }
  }
  keyframes_.reserve(keep.size());
  for (const size_t i : keep) {
    row_offset_.push_back(offsets[i]);
    feature_count_.push_back(counts[i]);
    positive_count_.push_back(positives[i]);
    num_features_ += counts[i];
    index_of_id_.emplace(all[i].id, static_cast<int>(keyframes_.size()));
    keyframes_.push_back(std::move(all[i]));
  }
  has_features_ = with_features;
  if (compact) {
    mapped_compact_keypoints_ = b + keypoints.offset + kf::kCompactKeypointPreambleBytes;
  } else {
    mapped_keypoints_ = file_keypoints;
  }
  mapped_descriptors_ = reinterpret_cast<const uint8_t*>(b + descriptors.offset);
  if (compact && with_features) {
    auto lazy = std::make_shared<LazyCheck>();
    lazy->shown = shown;
    lazy->sums.resize(2 * keep.size());
    for (size_t j = 0; j < keep.size(); ++j) {
      const char* entry = b + feature_blocks.offset + keep[j] * kf::kFeatureBlockEntryBytes;
      lazy->sums[2 * j] = Field<uint64_t>(entry, 0);
      lazy->sums[2 * j + 1] = Field<uint64_t>(entry, 8);
    }
    lazy->checked = std::make_unique<std::atomic<uint8_t>[]>(keep.size());
    lazy->keypoints = {b + keypoints.offset, keypoints.bytes, keypoints.checksum};
    lazy->descriptors = {b + descriptors.offset, descriptors.bytes, descriptors.checksum};
    if (whole_image.present) {
      lazy->whole_image = {b + whole_image.offset, whole_image.bytes, whole_image.checksum};
      // Rows copied for a subset were checked above.
      lazy->whole_image_checked.store(mapped_whole_image_ == nullptr);
    }
    lazy_ = std::move(lazy);
  }
  file_format_version_ = version;
  mapping_ = std::move(file);
  subset_ = options.subset;
  keyframes_in_file_ = num_keyframes;
}

Database Database::Load(const std::string& dir, const KeyframeSubset& subset) {
  LoadOptions options;
  options.subset = subset;
  return Load(dir, options);
}

Database Database::Load(const std::string& dir, const LoadOptions& options) {
  PLACEDB_CHECK_OPTIONS(options.subset);
  if (!HostIsLittleEndian()) PLACEDB_THROW_IO("placedb databases need a little-endian host");
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    PLACEDB_THROW_NOT_FOUND("no database at ", dir,
                            fs::exists(dir, ec) ? " (not a directory)" : " (no such directory)");
  }
  const std::string manifest_path = (fs::path(dir) / kManifestFile).string();
  // A rebuild may replace the files (or the whole directory) between our
  // reads: the manifest then names a file that is gone, and reading again
  // gives the new generation.
  constexpr int kAttempts = 8;
  for (int attempt = 1;; ++attempt) {
    const DirectoryHandle handle(dir);
    std::string text;
    if (!handle.ReadFile(kManifestFile, &text, kMaxManifestBytes)) {
      if (handle.MapFile("keyframes.bin") ||
          fs::exists(fs::path(dir) / "keyframes.writing.bin", ec)) {
        PLACEDB_THROW_CORRUPT("database ", dir, " is incomplete: ", kManifestFile, " is missing");
      }
      PLACEDB_THROW_NOT_FOUND("no database at ", dir, " (", kManifestFile, " is missing)");
    }
    nlohmann::json manifest =
        ParseJson(text, manifest_path, JsonOrigin::kDatabaseFile, kMaxManifestBytes);
    if (!manifest.is_object() || !manifest.contains("format") ||
        manifest["format"] != "placedb-database") {
      PLACEDB_THROW_CORRUPT(manifest_path, ": not a placedb database manifest");
    }
    const JsonReader m(manifest, manifest_path, JsonOrigin::kDatabaseFile);
    const int64_t version = m.Integer("format_version", 0, INT32_MAX);
    if (version == 1) {
      std::string source = "its source images";
      if (manifest.contains("source") && manifest["source"].is_string())
        source = manifest["source"].get<std::string>();
      PLACEDB_THROW_CORRUPT(
          dir, ": database format version 1 is no longer read (this placedb reads versions ",
          kOldestDatabaseFormatVersion, " to ", kDatabaseFormatVersion,
          "); rebuild it with `placedb build ... --out ", dir, " --overwrite` from ", source,
          " (the settings are in its manifest.json)");
    }
    if (version < kOldestDatabaseFormatVersion || version > kDatabaseFormatVersion) {
      PLACEDB_THROW_CORRUPT(dir, ": database format version ", version,
                            " is not supported (this placedb reads versions ",
                            kOldestDatabaseFormatVersion, " to ", kDatabaseFormatVersion, ")");
    }
    const JsonReader files = m.Child("files");
    const std::string name = files.String("keyframes");
    if (!IsKeyframesFileName(name) || name == "keyframes.bin")
      files.Fail("keyframes", "is not a keyframe file name");
    const uint64_t expected_bytes =
        static_cast<uint64_t>(files.Integer("keyframes_bytes", 0, INT64_MAX));
    const std::string expected_checksum = files.String("keyframes_checksum");
    const std::string feature_type = m.String("feature_type");
    const int64_t descriptor_bytes = m.Integer("descriptor_bytes", 0, INT32_MAX);
    // Absent in manifests of databases without the whole-image channel.
    const int64_t whole_image_dims =
        manifest.contains("whole_image_dims") ? m.Integer("whole_image_dims", 0, INT32_MAX) : 0;
    const JsonReader counts = m.Child("counts");
    const int64_t keyframes = counts.Integer("keyframes", 0, INT64_MAX);
    const int64_t features = counts.Integer("features", 0, INT64_MAX);

    std::shared_ptr<const MappedFile> file = handle.MapFile(name);
    const std::string shown = (fs::path(dir) / name).string();
    if (!file) {
      if (attempt < kAttempts) continue;  // replaced under us: read the manifest again
      PLACEDB_THROW_CORRUPT("database ", dir, " is incomplete: ", name, " (named by ",
                            kManifestFile, ") is missing");
    }
    if (file->size() != expected_bytes) {
      PLACEDB_THROW_CORRUPT(dir, ": ", name, " has ", file->size(), " bytes but ", kManifestFile,
                            " records ", expected_bytes, " (corrupted database)");
    }
    Database db;
    db.DecodeKeyframeFile(file, shown, options);
    const std::string checksum = ChecksumHex(Field<uint64_t>(file->data(), kf::kChecksumOffset));
    auto disagree = [&](const char* what) {
      PLACEDB_THROW_CORRUPT(dir, ": ", kManifestFile, " and ", name, " disagree on ", what,
                            " (corrupted database)");
    };
    if (checksum != expected_checksum) disagree("the file's checksum");
    if (static_cast<uint32_t>(version) != db.file_format_version_) disagree("the format version");
    if (feature_type != FeatureTypeName(db.feature_type_)) disagree("the feature type");
    if (descriptor_bytes != db.descriptor_bytes_) disagree("the descriptor width");
    if (whole_image_dims != db.whole_image_dims_) disagree("the whole-image channel");
    if (static_cast<uint64_t>(keyframes) != db.keyframes_in_file_)
      disagree("the number of keyframes");
    if (static_cast<uint64_t>(features) != Field<uint64_t>(file->data(), 40))
      disagree("the number of features");
    db.info_ = std::move(manifest);
    db.read_features_ =
        options.read_features || (options.read_features_above_bytes > 0 &&
                                  expected_bytes > options.read_features_above_bytes);
    db.keyframes_file_ = name;
    db.keyframes_bytes_ = expected_bytes;
    return db;
  }
}

}  // namespace placedb
