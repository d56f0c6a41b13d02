// The keyframe database: what is kept of every training frame (crop
// rectangle, stored-image geometry, pose, keypoints, descriptors), in flat
// arrays, and its on-disk form.
//
// On disk a database is a directory:
//   manifest.json   format version, every setting used to build it, counts,
//                   sizes, creation info; written last (atomically)
//   keyframes.bin   versioned, checksummed binary file (see database.cc)
//   images/         the stored (cropped, resized) PNGs, when kept
#pragma once

#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "placedb/feature/types.h"
#include "placedb/index/keyframe_subset.h"
#include "placedb/match/ratio_matcher.h"
#include "placedb/util/mapped_file.h"
#include "placedb/util/pose.h"

namespace placedb {

// Version of keyframes.bin and manifest.json this code writes and reads.
constexpr uint32_t kDatabaseFormatVersion = 1;

struct Keyframe {
  int32_t id = 0;             // the source frame's id
  double timestamp = -1.0;    // seconds, -1 when unknown
  std::optional<Pose> pose;   // ground-truth / map pose, when known
  cv::Rect crop;              // kept region, in the original image
  int32_t crop_channel = -1;  // winning chromaticity channel, -1: whole image
  cv::Size original_size;     // of the source image
  cv::Size stored_size;       // of the stored (cropped, resized) image
  double scale = 1.0;         // stored = (original - crop.tl()) * scale
  std::string source;         // path of the source image
  std::string image_file;     // stored PNG relative to the database dir ("" if none)

  // Maps a point of the stored image back to the original image.
  cv::Point2f ToOriginal(const cv::Point2f& stored) const {
    return {static_cast<float>(stored.x / scale + crop.x),
            static_cast<float>(stored.y / scale + crop.y)};
  }
};

class Database {
 public:
  Database() = default;
  // An empty database for descriptors of `type`, `descriptor_bytes` per row.
  Database(FeatureType type, int descriptor_bytes);

  FeatureType feature_type() const { return feature_type_; }
  int descriptor_bytes() const { return descriptor_bytes_; }
  // Keyframes (and their features) in this database: all of the file's, or
  // the subset it was opened with.
  size_t size() const { return keyframes_.size(); }
  bool empty() const { return keyframes_.empty(); }
  size_t num_features() const { return keypoints_.size(); }
  // What Load kept of the file, and how many keyframes the file holds.
  const KeyframeSubset& subset() const { return subset_; }
  size_t keyframes_in_file() const { return keyframes_in_file_; }

  const Keyframe& keyframe(size_t index) const { return keyframes_[index]; }
  const std::vector<Keyframe>& keyframes() const { return keyframes_; }
  // Index of the keyframe with this id, or -1.
  int IndexOfId(int32_t id) const;

  // Keypoints (stored-image coordinates) and a view of the descriptors of
  // keyframe `index`; valid while the database is alive and unchanged.
  std::vector<cv::KeyPoint> Keypoints(size_t index) const;
  DescriptorBlock Descriptors(size_t index) const;
  size_t FeatureCount(size_t index) const { return feature_count_[index]; }

  // Appends a keyframe with its features; the features' type and width must
  // match the database's (std::invalid_argument otherwise). Ids must be unique.
  void AddKeyframe(Keyframe keyframe, const FeatureSet& features);

  // Everything about how the database was built, free-form JSON kept in the
  // manifest (settings, source, sizes). Set by the builder.
  nlohmann::json& info() { return info_; }
  const nlohmann::json& info() const { return info_; }

  // Writes manifest.json and keyframes.bin into `dir` (which must exist):
  // each file via temporary file + fsync + rename, manifest last.
  void Save(const std::string& dir) const;

  // Opens a database directory, or only `subset` of its keyframes: the others'
  // keypoints and strings are not decoded, their descriptors never touched.
  // Throws std::runtime_error with a clear message for a missing, truncated,
  // corrupted (checksum), wrong-magic or wrong-version database, or one whose
  // manifest and binary disagree; std::invalid_argument for a bad subset (an
  // id that is not in the file). Saving a subset writes just that subset.
  static Database Load(const std::string& dir, const KeyframeSubset& subset = KeyframeSubset());

  // Name of the binary file inside the database directory.
  static constexpr const char* kKeyframesFile = "keyframes.bin";
  static constexpr const char* kManifestFile = "manifest.json";

 private:
  std::string EncodeKeyframes() const;
  void DecodeKeyframes(std::shared_ptr<const MappedFile> file, const std::string& path,
                       const KeyframeSubset& subset);
  // Start of the flat descriptor array: owned, or inside the mapped file.
  const uint8_t* DescriptorData() const {
    return mapping_ ? mapped_descriptors_ : descriptors_.data();
  }

  FeatureType feature_type_ = FeatureType::kOrb;
  int descriptor_bytes_ = 32;
  std::vector<Keyframe> keyframes_;
  std::unordered_map<int32_t, int> index_of_id_;  // keyframe id -> index
  // Flat feature storage: keyframe i owns descriptor rows [row_offset_[i],
  // row_offset_[i] + feature_count_[i]) of the descriptor array (the file's,
  // when mapped), and keypoints / Laplacian signs from local_offset_[i] on.
  // The two offsets differ only for a subset of a mapped file.
  std::vector<uint64_t> row_offset_;
  std::vector<uint64_t> local_offset_;
  std::vector<uint32_t> feature_count_;
  std::vector<cv::KeyPoint> keypoints_;
  // num_features * descriptor_bytes. A loaded database uses the descriptors
  // in place in the memory-mapped keyframes.bin instead (mapping_ set); the
  // first AddKeyframe copies them here.
  std::vector<uint8_t> descriptors_;
  std::shared_ptr<const MappedFile> mapping_;
  const uint8_t* mapped_descriptors_ = nullptr;
  std::vector<int8_t> laplacian_;  // SURF: sign of the Laplacian per feature
  nlohmann::json info_ = nlohmann::json::object();
  KeyframeSubset subset_;
  size_t keyframes_in_file_ = 0;
};

}  // namespace placedb
