#include "placedb/index/database.h"

#include <cstring>
#include <filesystem>
#include <optional>
#include <string_view>
#include <unordered_set>

#include "placedb/util/check.h"
#include "placedb/util/file_io.h"

// keyframes.bin, format version 1. All values little-endian.
//   char[8]  magic "PLDBKF\r\n" (the CR LF catches text-mode mangling)
//   u32      format version
//   u32      feature type (1 ORB, 2 SURF)
//   u32      descriptor bytes per row
//   u32      reserved (0)
//   u64      number of keyframes K
//   u64      number of features F
//   u64      bytes of the string table S
//   K x keyframe record (fixed 152 bytes, see EncodeKeyframes)
//   F x keypoint record (x, y, size, angle, response: f32; octave, class_id: i32)
//   padding to a multiple of 32 bytes
//   F x descriptor row (descriptor bytes each): a flat array, mappable as is
//   S bytes of string table (keyframe sources and stored image names)
//   u32      CRC-32 of every byte before it
namespace placedb {
namespace fs = std::filesystem;
namespace {

constexpr char kMagic[8] = {'P', 'L', 'D', 'B', 'K', 'F', '\r', '\n'};
constexpr size_t kDescriptorAlignment = 32;

}  // namespace

Database::Database(FeatureType type, int descriptor_bytes)
    : feature_type_(type), descriptor_bytes_(descriptor_bytes) {
  PLACEDB_CHECK(descriptor_bytes > 0, "descriptor width must be positive");
}

int Database::IndexOfId(int32_t id) const {
  const auto it = index_of_id_.find(id);
  return it == index_of_id_.end() ? -1 : it->second;
}

std::vector<cv::KeyPoint> Database::Keypoints(size_t index) const {
  const auto begin = keypoints_.begin() + static_cast<ptrdiff_t>(local_offset_[index]);
  return std::vector<cv::KeyPoint>(begin, begin + feature_count_[index]);
}

DescriptorBlock Database::Descriptors(size_t index) const {
  DescriptorBlock block;
  block.type = feature_type_;
  block.rows = static_cast<int>(feature_count_[index]);
  block.row_bytes = descriptor_bytes_;
  block.data = DescriptorData() + row_offset_[index] * descriptor_bytes_;
  if (feature_type_ == FeatureType::kSurf) {
    block.laplacian = laplacian_.data() + local_offset_[index];
  }
  return block;
}

void Database::AddKeyframe(Keyframe keyframe, const FeatureSet& features) {
  if (features.type != feature_type_) {
    PLACEDB_THROW_INVALID("cannot add ", FeatureTypeName(features.type),
                          " features to a database of ", FeatureTypeName(feature_type_),
                          " features");
  }
  const int row_bytes =
      static_cast<int>(features.descriptors.cols * features.descriptors.elemSize());
  PLACEDB_CHECK(features.empty() || row_bytes == descriptor_bytes_, "descriptor width ", row_bytes,
                " differs from the database's ", descriptor_bytes_);
  PLACEDB_CHECK(features.descriptors.rows == static_cast<int>(features.keypoints.size()),
                "one descriptor per keypoint expected");
  PLACEDB_CHECK(IndexOfId(keyframe.id) < 0, "duplicate keyframe id ", keyframe.id);
  if (mapping_) {
    // Copy on write: the mapped file is read-only. Only this database's
    // keyframes are copied, back to back, so rows and keypoints align again.
    std::vector<uint8_t> owned;
    owned.reserve(keypoints_.size() * descriptor_bytes_);
    for (size_t i = 0; i < keyframes_.size(); ++i) {
      const DescriptorBlock block = Descriptors(i);
      owned.insert(owned.end(), block.data,
                   block.data + static_cast<size_t>(block.rows) * block.row_bytes);
    }
    descriptors_ = std::move(owned);
    row_offset_ = local_offset_;
    mapping_.reset();
    mapped_descriptors_ = nullptr;
  }
  row_offset_.push_back(keypoints_.size());
  local_offset_.push_back(keypoints_.size());
  feature_count_.push_back(static_cast<uint32_t>(features.keypoints.size()));
  keypoints_.insert(keypoints_.end(), features.keypoints.begin(), features.keypoints.end());
  for (int r = 0; r < features.descriptors.rows; ++r) {
    const uint8_t* row = features.descriptors.ptr<uint8_t>(r);
    descriptors_.insert(descriptors_.end(), row, row + descriptor_bytes_);
  }
  for (const cv::KeyPoint& kp : features.keypoints) {
    laplacian_.push_back(kp.class_id < 0 ? -1 : 1);
  }
  index_of_id_.emplace(keyframe.id, static_cast<int>(keyframes_.size()));
  keyframes_.push_back(std::move(keyframe));
  keyframes_in_file_ = keyframes_.size();
}

std::string Database::EncodeKeyframes() const {
  BinaryWriter w;
  w.PutBytes(kMagic, sizeof(kMagic));
  w.Put<uint32_t>(kDatabaseFormatVersion);
  w.Put<uint32_t>(static_cast<uint32_t>(feature_type_));
  w.Put<uint32_t>(static_cast<uint32_t>(descriptor_bytes_));
  w.Put<uint32_t>(0);
  w.Put<uint64_t>(keyframes_.size());
  w.Put<uint64_t>(keypoints_.size());
  std::string strings;
  for (const Keyframe& k : keyframes_) strings += k.source + k.image_file;
  w.Put<uint64_t>(strings.size());

  uint64_t string_offset = 0;
  for (size_t i = 0; i < keyframes_.size(); ++i) {
    const Keyframe& k = keyframes_[i];
    w.Put<int32_t>(k.id);
    w.Put<int32_t>(k.crop_channel);
    w.Put<int32_t>(k.crop.x);
    w.Put<int32_t>(k.crop.y);
    w.Put<int32_t>(k.crop.width);
    w.Put<int32_t>(k.crop.height);
    w.Put<int32_t>(k.original_size.width);
    w.Put<int32_t>(k.original_size.height);
    w.Put<int32_t>(k.stored_size.width);
    w.Put<int32_t>(k.stored_size.height);
    w.Put<double>(k.timestamp);
    w.Put<double>(k.scale);
    w.Put<uint32_t>(k.pose ? 1u : 0u);
    w.Put<uint32_t>(0u);
    const Pose pose = k.pose.value_or(Pose());
    w.Put<double>(pose.translation.x());
    w.Put<double>(pose.translation.y());
    w.Put<double>(pose.translation.z());
    w.Put<double>(pose.rotation.x());
    w.Put<double>(pose.rotation.y());
    w.Put<double>(pose.rotation.z());
    w.Put<double>(pose.rotation.w());
    w.Put<uint64_t>(local_offset_[i]);  // rows are written back to back below
    w.Put<uint32_t>(feature_count_[i]);
    w.Put<uint32_t>(static_cast<uint32_t>(k.source.size()));
    w.Put<uint64_t>(string_offset);
    w.Put<uint32_t>(static_cast<uint32_t>(k.image_file.size()));
    w.Put<uint32_t>(0u);
    string_offset += k.source.size() + k.image_file.size();
  }
  for (const cv::KeyPoint& kp : keypoints_) {
    w.Put<float>(kp.pt.x);
    w.Put<float>(kp.pt.y);
    w.Put<float>(kp.size);
    w.Put<float>(kp.angle);
    w.Put<float>(kp.response);
    w.Put<int32_t>(kp.octave);
    w.Put<int32_t>(kp.class_id);
  }
  w.Align(kDescriptorAlignment);
  for (size_t i = 0; i < keyframes_.size(); ++i) {
    const DescriptorBlock block = Descriptors(i);
    w.PutArray(block.data, static_cast<size_t>(block.rows) * block.row_bytes);
  }
  w.PutBytes(strings.data(), strings.size());
  const uint32_t crc = Crc32(w.buffer().data(), w.size());
  w.Put<uint32_t>(crc);
  return w.buffer();
}

void Database::DecodeKeyframes(std::shared_ptr<const MappedFile> file, const std::string& path,
                               const KeyframeSubset& subset) {
  const std::string_view bytes(file->data(), file->size());
  if (!HostIsLittleEndian()) PLACEDB_THROW_RUNTIME("placedb databases need a little-endian host");
  // A file cut inside the magic (a prefix of it, or empty) is truncated, not
  // a different kind of file.
  if (bytes.size() < sizeof(kMagic) &&
      (bytes.empty() || std::memcmp(bytes.data(), kMagic, bytes.size()) == 0)) {
    PLACEDB_THROW_RUNTIME(path, ": file is truncated (", bytes.size(), " bytes)");
  }
  if (bytes.size() < sizeof(kMagic) || std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) {
    PLACEDB_THROW_RUNTIME(path, ": not a placedb keyframe file (wrong magic)");
  }
  BinaryReader header(bytes.data(), bytes.size(), path);
  char magic[8];
  header.GetBytes(magic, sizeof(magic));
  const uint32_t version = header.Get<uint32_t>();
  if (version != kDatabaseFormatVersion) {
    PLACEDB_THROW_RUNTIME(path, ": format version ", version,
                          " is not supported (this placedb reads version ", kDatabaseFormatVersion,
                          ")");
  }
  if (bytes.size() < sizeof(kMagic) + 4 + 4) {
    PLACEDB_THROW_RUNTIME(path, ": file is truncated");
  }
  // The checksum covers everything but itself: verify before trusting counts.
  // A truncated file fails here too, with its own message.
  const uint32_t type = header.Get<uint32_t>();
  const uint32_t row_bytes = header.Get<uint32_t>();
  header.Get<uint32_t>();
  const uint64_t num_keyframes = header.Get<uint64_t>();
  const uint64_t num_features = header.Get<uint64_t>();
  const uint64_t string_bytes = header.Get<uint64_t>();
  constexpr uint64_t kKeyframeRecord = 152;
  constexpr uint64_t kKeypointRecord = 28;
  uint64_t expected =
      header.position() + num_keyframes * kKeyframeRecord + num_features * kKeypointRecord;
  expected = (expected + kDescriptorAlignment - 1) / kDescriptorAlignment * kDescriptorAlignment;
  expected += num_features * row_bytes + string_bytes + 4;
  if (num_keyframes > bytes.size() || num_features > bytes.size() || string_bytes > bytes.size() ||
      row_bytes > 4096 || bytes.size() < expected) {
    PLACEDB_THROW_RUNTIME(path, ": file is truncated (", bytes.size(), " bytes, header says ",
                          expected, ")");
  }
  if (bytes.size() != expected) {
    PLACEDB_THROW_RUNTIME(path, ": file has ", bytes.size() - expected,
                          " unexpected trailing bytes (corrupted)");
  }
  uint32_t stored_crc;
  std::memcpy(&stored_crc, bytes.data() + bytes.size() - 4, 4);
  if (Crc32(bytes.data(), bytes.size() - 4) != stored_crc) {
    PLACEDB_THROW_RUNTIME(path, ": checksum mismatch (the file is corrupted)");
  }
  if (type != static_cast<uint32_t>(FeatureType::kOrb) &&
      type != static_cast<uint32_t>(FeatureType::kSurf)) {
    PLACEDB_THROW_RUNTIME(path, ": unknown feature type ", type);
  }
  feature_type_ = static_cast<FeatureType>(type);
  descriptor_bytes_ = static_cast<int>(row_bytes);

  // Every keyframe record is read (they are small and hold the ids); only the
  // kept keyframes' keypoints and strings are decoded.
  BinaryReader r = header;
  struct Record {
    Keyframe keyframe;
    uint64_t feature_offset = 0;
    uint32_t feature_count = 0;
    uint64_t string_offset = 0;
    uint32_t source_len = 0, image_len = 0;
  };
  std::vector<Record> records(num_keyframes);
  std::vector<int32_t> ids(num_keyframes);
  for (uint64_t i = 0; i < num_keyframes; ++i) {
    Record& rec = records[i];
    Keyframe& k = rec.keyframe;
    k.id = r.Get<int32_t>();
    k.crop_channel = r.Get<int32_t>();
    k.crop.x = r.Get<int32_t>();
    k.crop.y = r.Get<int32_t>();
    k.crop.width = r.Get<int32_t>();
    k.crop.height = r.Get<int32_t>();
    k.original_size.width = r.Get<int32_t>();
    k.original_size.height = r.Get<int32_t>();
    k.stored_size.width = r.Get<int32_t>();
    k.stored_size.height = r.Get<int32_t>();
    k.timestamp = r.Get<double>();
    k.scale = r.Get<double>();
    const bool has_pose = r.Get<uint32_t>() != 0;
    r.Get<uint32_t>();
    Pose pose;
    const double tx = r.Get<double>(), ty = r.Get<double>(), tz = r.Get<double>();
    const double qx = r.Get<double>(), qy = r.Get<double>(), qz = r.Get<double>(),
                 qw = r.Get<double>();
    pose.translation = Eigen::Vector3d(tx, ty, tz);
    pose.rotation = Eigen::Quaterniond(qw, qx, qy, qz);
    if (has_pose) k.pose = pose;
    rec.feature_offset = r.Get<uint64_t>();
    rec.feature_count = r.Get<uint32_t>();
    rec.source_len = r.Get<uint32_t>();
    rec.string_offset = r.Get<uint64_t>();
    rec.image_len = r.Get<uint32_t>();
    r.Get<uint32_t>();
    if (rec.feature_offset > num_features ||
        rec.feature_count > num_features - rec.feature_offset) {
      PLACEDB_THROW_RUNTIME(path, ": keyframe ", k.id, " refers to features beyond the file");
    }
    if (rec.string_offset > string_bytes ||
        uint64_t{rec.source_len} + rec.image_len > string_bytes - rec.string_offset) {
      PLACEDB_THROW_RUNTIME(path, ": keyframe ", k.id, " refers to strings beyond the file");
    }
    ids[i] = k.id;
  }
  {
    std::unordered_set<int32_t> seen;
    for (const int32_t id : ids) {
      if (!seen.insert(id).second)
        PLACEDB_THROW_RUNTIME(path, ": keyframe id ", id, " appears twice");
    }
  }
  const std::vector<size_t> keep = SelectKeyframes(subset, num_keyframes, ids);
  const size_t keypoints_at = r.position();
  constexpr size_t kKeypointBytes = 28;
  size_t descriptors_at = keypoints_at + num_features * kKeypointBytes;
  descriptors_at =
      (descriptors_at + kDescriptorAlignment - 1) / kDescriptorAlignment * kDescriptorAlignment;
  const size_t strings_at = descriptors_at + num_features * row_bytes;
  size_t kept_features = 0;
  for (const size_t i : keep) kept_features += records[i].feature_count;
  keyframes_.reserve(keep.size());
  keypoints_.reserve(kept_features);
  laplacian_.reserve(kept_features);
  for (const size_t i : keep) {
    Record& rec = records[i];
    BinaryReader kr(bytes.data() + keypoints_at + rec.feature_offset * kKeypointBytes,
                    rec.feature_count * kKeypointBytes, path);
    row_offset_.push_back(rec.feature_offset);
    local_offset_.push_back(keypoints_.size());
    feature_count_.push_back(rec.feature_count);
    for (uint32_t f = 0; f < rec.feature_count; ++f) {
      cv::KeyPoint kp;
      kp.pt.x = kr.Get<float>();
      kp.pt.y = kr.Get<float>();
      kp.size = kr.Get<float>();
      kp.angle = kr.Get<float>();
      kp.response = kr.Get<float>();
      kp.octave = kr.Get<int32_t>();
      kp.class_id = kr.Get<int32_t>();
      keypoints_.push_back(kp);
      laplacian_.push_back(kp.class_id < 0 ? -1 : 1);
    }
    const char* strings = bytes.data() + strings_at + rec.string_offset;
    rec.keyframe.source.assign(strings, rec.source_len);
    rec.keyframe.image_file.assign(strings + rec.source_len, rec.image_len);
    index_of_id_.emplace(rec.keyframe.id, static_cast<int>(keyframes_.size()));
    keyframes_.push_back(std::move(rec.keyframe));
  }
  // The descriptors stay where they are, in the mapping (32-byte aligned in
  // the file, and mmap returns page-aligned memory).
  mapped_descriptors_ = reinterpret_cast<const uint8_t*>(file->data()) + descriptors_at;
  mapping_ = std::move(file);
  subset_ = subset;
  keyframes_in_file_ = num_keyframes;
}

void Database::Save(const std::string& dir) const {
  PLACEDB_CHECK(fs::is_directory(dir), "database directory does not exist: ", dir);
  const std::string bytes = EncodeKeyframes();
  WriteFileAtomic((fs::path(dir) / kKeyframesFile).string(), bytes);
  nlohmann::json manifest = info_;
  manifest["format"] = "placedb-database";
  manifest["format_version"] = kDatabaseFormatVersion;
  manifest["feature_type"] = FeatureTypeName(feature_type_);
  manifest["descriptor_bytes"] = descriptor_bytes_;
  manifest["counts"]["keyframes"] = keyframes_.size();
  manifest["counts"]["features"] = keypoints_.size();
  if (!subset_.all()) manifest["subset_of"] = {{"subset", subset_.Describe()}};
  manifest["files"]["keyframes"] = kKeyframesFile;
  manifest["files"]["keyframes_bytes"] = bytes.size();
  manifest["files"]["keyframes_crc32"] = Crc32(bytes.data(), bytes.size());
  WriteFileAtomic((fs::path(dir) / kManifestFile).string(), manifest.dump(2) + "\n");
}

Database Database::Load(const std::string& dir, const KeyframeSubset& subset) {
  PLACEDB_CHECK_OPTIONS(subset);
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    PLACEDB_THROW_RUNTIME("no database at ", dir, " (not a directory)");
  const std::string manifest_path = (fs::path(dir) / kManifestFile).string();
  if (!fs::exists(manifest_path, ec)) {
    PLACEDB_THROW_RUNTIME("no database at ", dir, " (", kManifestFile, " is missing)");
  }
  nlohmann::json manifest;
  try {
    manifest = nlohmann::json::parse(ReadFileToString(manifest_path));
  } catch (const nlohmann::json::exception& e) {
    PLACEDB_THROW_RUNTIME(manifest_path, ": not valid JSON (", e.what(), ")");
  }
  // Fields of the wrong JSON type would throw nlohmann's type_error, which is
  // no std::runtime_error: read them all here and report a malformed manifest.
  std::string format, manifest_type;
  uint32_t version = 0;
  std::optional<uint64_t> manifest_keyframes;
  try {
    if (manifest.is_object()) {
      format = manifest.value("format", "");
      version = manifest.value("format_version", 0u);
      manifest_type = manifest.value("feature_type", "");
      if (manifest.contains("counts")) {
        manifest_keyframes = manifest["counts"].value("keyframes", uint64_t{0});
      }
    }
  } catch (const nlohmann::json::exception& e) {
    PLACEDB_THROW_RUNTIME(manifest_path, ": malformed manifest (", e.what(), ")");
  }
  if (!manifest.is_object() || format != "placedb-database") {
    PLACEDB_THROW_RUNTIME(manifest_path, ": not a placedb database manifest");
  }
  if (version != kDatabaseFormatVersion) {
    PLACEDB_THROW_RUNTIME(dir, ": database format version ", version,
                          " is not supported (this placedb reads version ", kDatabaseFormatVersion,
                          ")");
  }
  const std::string bin_path = (fs::path(dir) / kKeyframesFile).string();
  if (!fs::exists(bin_path, ec)) {
    PLACEDB_THROW_RUNTIME("database ", dir, " is incomplete: ", kKeyframesFile, " is missing");
  }
  Database db;
  db.DecodeKeyframes(MappedFile::Open(bin_path), bin_path, subset);
  if (manifest_type != FeatureTypeName(db.feature_type_)) {
    PLACEDB_THROW_RUNTIME(dir, ": manifest says '", manifest_type, "' features but ",
                          kKeyframesFile, " holds '", FeatureTypeName(db.feature_type_),
                          "' features (corrupted database)");
  }
  if (manifest_keyframes && *manifest_keyframes != db.keyframes_in_file_) {
    PLACEDB_THROW_RUNTIME(dir, ": manifest and ", kKeyframesFile,
                          " disagree on the number of keyframes (corrupted database)");
  }
  db.info_ = manifest;
  return db;
}

}  // namespace placedb
