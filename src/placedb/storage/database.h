// The keyframe database: what is kept of every training frame (crop
// rectangle, stored-image geometry, pose, keypoints, descriptors), in flat
// arrays, and its on-disk form.
//
// On disk a database is a directory:
//   manifest.json                format version, every setting used to build it,
//                                counts, sizes, creation info, and the name, size
//                                and checksum of the keyframe file it goes with
//   keyframes.<checksum>.bin     the keyframe file, format version 3 (2 is
//                                read too; see keyframe_file.h): a new name
//                                for every content
//   images/                      the stored (cropped, resized) PNGs, when kept
//
// The manifest names its keyframe file, so a reader can never pair a manifest
// with another build's keyframes, and a save in place writes the new file
// under its new name before the manifest switches to it: a crash at any point
// leaves the old database or the new one.
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
#include "placedb/match/ratio_matcher.h"
#include "placedb/storage/keyframe.h"
#include "placedb/storage/keyframe_subset.h"
#include "placedb/util/mapped_file.h"
#include "placedb/util/pose.h"
#include "placedb/util/span.h"

namespace placedb {

// Version of the keyframe file and manifest this code writes, and the
// oldest it reads (a version 2 database opens, answers as before, and is
// written as version 3 by its next save).
constexpr uint32_t kDatabaseFormatVersion = 3;
constexpr uint32_t kOldestDatabaseFormatVersion = 2;

// Why a keyframe record is impossible, or "" when it is fine: an id below 1, a
// crop channel outside [-1, 2], a negative size or crop, an image side above
// 2^20 pixels, a crop outside a known original size, a scale that is not finite and in (0, 64], a
// timestamp that is not finite, a pose with non-finite values or a quaternion that is not of unit
// length, paths longer than 64 KiB, a source path holding a NUL byte, a stored image name that is
// not IsStoredImageName. The source path may hold any other bytes (it is the user's path, used
// only to read that image back); it is escaped when printed (EscapeForTerminal) and JSON turns
// bytes that are not UTF-8 into U+FFFD (DumpJson).
std::string CheckKeyframe(const Keyframe& keyframe);

// The folder of the stored images inside a database directory.
constexpr char kStoredImageFolder[] = "images";
// Whether `name` may be a keyframe's image_file: "" (no stored image) or
// exactly "images/<name>" where <name> is IsPlainFileName (util/file_io.h):
// one name of [A-Za-z0-9._-], 1 to 255 bytes, not starting with '.'. So no
// further separator, no "..", no absolute path, no control character or NUL,
// nothing that is not printable ASCII: joined to the database directory it
// names a file inside its images folder, whatever the database file says.
bool IsStoredImageName(const std::string& name);

// Keypoint and descriptor values a database accepts (AddKeyframe, Load) and
// a query must have (ValidateQueryFeatures).
// Why `keypoints` cannot belong to an image of `image_size`, or "": a
// position, size, angle or response that is not finite, or a position
// outside the image by more than kKeypointTolerancePx (0 <= x <= width
// within the tolerance; an unknown size, 0 x 0, bounds positions by the
// largest image side, 2^20). Extraction puts keypoints in [0, width) x
// [0, height); the tolerance covers rounding when keypoints are moved into a
// crop or scaled back from an upscaled frame.
constexpr float kKeypointTolerancePx = 1.0f;
std::string CheckKeypoints(const cv::KeyPoint* keypoints, size_t count, cv::Size image_size);
// Whether all `count` floats are finite (SURF descriptor rows): one
// vectorisable pass.
bool AllFinite(const float* values, size_t count);

// What Load reads of the keyframe file.
enum class LoadContents {
  kAll,            // keyframes, keypoints and descriptors
  kKeyframeTable,  // ids, poses, crops, paths and feature counts only (a voter's
                   // view): keypoints and descriptors are neither read nor checked
};

struct LoadOptions {
  KeyframeSubset subset;
  LoadContents contents = LoadContents::kAll;
  // A version 3 file's features are read from the file (pread) for each
  // use by a query (Database::Descriptors with a buffer, Keypoints) instead
  // of through the mapping: the process's resident memory does not grow by
  // the keyframes its queries examine (they stay in the kernel's page
  // cache), at the cost of a read per candidate. Other uses (a build, an
  // index build, the exhaustive baseline) and version 2 files use the
  // mapping as before; a database that is changed (AddKeyframe) keeps its
  // features in memory.
  bool read_features = false;
  // The same, decided by size: features are read when the keyframe file is
  // larger than this many bytes (0: size never decides; read_features
  // alone does).
  uint64_t read_features_above_bytes = 0;
};

class Database {
 public:
  Database() = default;
  // An empty database for descriptors of `type`, `descriptor_bytes` per row
  // (32 for ORB; 256 or 512 for SURF), with a whole-image channel of
  // `whole_image_dims` values per keyframe (0: none; else in [16, 4096]).
  Database(FeatureType type, int descriptor_bytes, int whole_image_dims = 0);

  FeatureType feature_type() const { return feature_type_; }
  int descriptor_bytes() const { return descriptor_bytes_; }
  // Keyframes (and their features) in this database: all of the file's, or
  // the subset it was opened with.
  size_t size() const { return keyframes_.size(); }
  bool empty() const { return keyframes_.empty(); }
  size_t num_features() const { return num_features_; }
  // What Load kept of the file, and how many keyframes the file holds.
  const KeyframeSubset& subset() const { return subset_; }
  size_t keyframes_in_file() const { return keyframes_in_file_; }
  // False for a database loaded as a keyframe table (LoadContents): then
  // Keypoints and Descriptors must not be called.
  bool has_features() const { return has_features_; }

  const Keyframe& keyframe(size_t index) const { return keyframes_[index]; }
  const std::vector<Keyframe>& keyframes() const { return keyframes_; }
  // Index of the keyframe with this id, or -1.
  int IndexOfId(int32_t id) const;

  // Keypoints (stored-image coordinates, a copy: a version 3 file keeps
  // them compact, storage/compact_keypoint.h) and descriptors (a view valid
  // while the database is alive and unchanged) of keyframe `index`. SURF
  // rows are grouped by the sign of the Laplacian: the block's first
  // positive_rows rows have sign +1 (keypoint class_id >= 0), the rest -1.
  //
  // Integrity: a version 3 database read from its file checks a keyframe's
  // features the first time they are asked for (their two block checksums,
  // then the values: keypoints inside the stored image, SURF rows finite
  // and grouped by sign), and the whole-image rows the first time they are
  // asked for; so no byte influences an answer unchecked, and opening
  // touches only the keyframe table. Damage found then is CorruptDatabase
  // (from these accessors, so from the query that asked). A version 2 file
  // is checked whole on open, as before. Thread-safe.
  std::vector<cv::KeyPoint> Keypoints(size_t index) const;
  DescriptorBlock Descriptors(size_t index) const;
  // The same rows for a query's own, short use: with
  // LoadOptions::read_features (and the features used in place from a
  // version 3 file) they are read from the file into *buffer, and checked
  // as read if their first use is now, and the view is valid until *buffer
  // changes; otherwise this is Descriptors(index) and *buffer is unused.
  DescriptorBlock Descriptors(size_t index, std::vector<uint8_t>* buffer) const;
  // Whether Descriptors(index, buffer) and Keypoints read from the file.
  bool reads_features() const {
    return read_features_ && mapping_ && mapped_compact_keypoints_ != nullptr;
  }
  // Checks now every byte of the database that is not yet checked (what
  // `placedb verify` runs): the keypoint, descriptor and whole-image
  // sections' checksums and every keyframe's features. CorruptDatabase on
  // the first damage found; nothing to do for a built database or a
  // version 2 file (checked on open).
  void VerifyAll() const;
  // Whether keyframe `index`'s features have been checked (always true but
  // for a version 3 file's keyframes not used yet).
  bool FeaturesChecked(size_t index) const;
  // Checks, as their first use would, the features of the keyframes from
  // *next on that are not checked yet, at most `max_keyframes` of them,
  // reading their bytes from the file (MappedFile::ReadAt into `buffer`),
  // not through the mapping: the process's resident memory does not grow.
  // A keyframe that passes is marked checked; one that fails is left as it
  // was, for its first use to report. Advances *next; returns whether
  // keyframes are left after it (false at once for a database with nothing
  // to check). For a session's background thread (OpenOptions::prefetch):
  // thread-safe against readers, not against changes of the database.
  bool CheckSomeInBackground(size_t* next, size_t max_keyframes,
                             std::vector<uint8_t>* buffer) const;
  // The version of the keyframe file this database was read from (0: never
  // read from a file).
  uint32_t file_format_version() const { return file_format_version_; }
  // The keyframe file the features are used from in place (nullptr: built
  // or grown in memory); for prefetching and releasing its pages
  // (util/mapped_file.h).
  const std::shared_ptr<const MappedFile>& mapped_file() const { return mapping_; }
  size_t FeatureCount(size_t index) const { return feature_count_[index]; }

  // The whole-image channel (feature/whole_image.h): one row of
  // whole_image_dims() int8 values per keyframe, 0 when the database has
  // none (built without it, or by an earlier placedb). WholeImageData() is
  // size() rows back to back in keyframe index order (nullptr without a
  // channel), valid while the database is alive and unchanged; WholeImage(i)
  // is keyframe i's row. A keyframe table (has_features() false) has no rows
  // to give (InvalidArgument), but says its dims. The first call checks the
  // rows of a version 3 file (CorruptDatabase when damaged).
  int whole_image_dims() const { return whole_image_dims_; }
  const int8_t* WholeImageData() const;
  const int8_t* WholeImage(size_t index) const {
    return WholeImageData() + index * static_cast<size_t>(whole_image_dims_);
  }
  // The rows the whole-image channel standardises a query's similarities
  // over, `*count` of them: for a subset loaded from a file, every row of
  // the file (so that every subset of one file, and the whole, standardise
  // alike and their answers merge exactly); else WholeImageData()'s size().
  const int8_t* StandardisingRows(size_t* count) const;

  // Appends a keyframe with its features. InvalidArgument when the
  // keyframe is impossible (CheckKeyframe), its id is taken, or the features'
  // type, width or count disagree with the database, or a keypoint is not
  // finite or lies outside the stored image (CheckKeypoints), or a SURF
  // descriptor value is not finite, or (a database with a whole-image
  // channel) features.whole_image is not a continuous 1 x whole_image_dims()
  // CV_8S row of values in [-127, 127]. A database without the channel
  // ignores a row given. SURF features are reordered, positive Laplacian
  // first.
  void AddKeyframe(Keyframe keyframe, const FeatureSet& features);
  // Room for keyframes and feature rows to be appended without moving any
  // storage (a database used in place from its file has none: the first
  // AddKeyframe copies it). Reserve makes that room (and copies a mapped
  // database into owned storage). For online mapping: grow a copy where no
  // reader looks, then append in place.
  bool HasRoomFor(size_t keyframes, size_t features) const;
  void Reserve(size_t keyframes, size_t features);
  // The keyframes whose `keep` flag is set (keep.size() == size()), in the
  // same order, with their features and this database's info.
  Database Compacted(const std::vector<char>& keep) const;
  // The features of keyframe `index` as a FeatureSet (a copy), with its
  // whole-image row when the database has the channel.
  FeatureSet Features(size_t index) const;

  // Everything about how the database was built, free-form JSON kept in the
  // manifest (settings, source, sizes). Set by the builder.
  nlohmann::json& info() { return info_; }
  const nlohmann::json& info() const { return info_; }

  // Writes the database into `dir` (which must exist): the keyframe file
  // streamed under its content-named file name, then the manifest, each via
  // a temporary file, fsync and rename; then the previous generation's
  // keyframe file is removed. Saving over an existing database is
  // crash-safe. One writer at a time per directory.
  struct SaveResult {
    std::string keyframes_file;  // name inside `dir`
    uint64_t keyframes_bytes = 0;
  };
  SaveResult Save(const std::string& dir) const;

  // Opens a database directory (or only a subset of it, or only its keyframe
  // table). The manifest and the keyframe file it names are read relative to
  // one open directory and checked against each other (name, size, checksum,
  // counts, feature type and width, whole-image channel), so a rebuild between the two reads
  // cannot mix generations; a rebuild that replaces the file under a reader
  // makes it read the new generation (a few retries). Every header field,
  // offset, count, size and checksum of the file is checked before use.
  // Errors: NotFound when `dir` holds no database (no folder, no manifest);
  // Opening a version 3 file checks its header, section table, keyframe
  // records, strings and block checksum table; the features are checked on
  // first use (Keypoints, "Integrity").
  // CorruptDatabase with a clear message for a truncated, corrupted,
  // wrong-magic or wrong-version database (a version 1 database says how to
  // rebuild it), one that misses a file its manifest names, or one whose
  // manifest and file disagree; InvalidArgument for a bad subset (an id that
  // is not in the file). Saving a subset writes just that subset, and only
  // into a folder that holds no database (InvalidArgument otherwise: the
  // subset would replace the whole database).
  static Database Load(const std::string& dir, const LoadOptions& options);
  static Database Load(const std::string& dir, const KeyframeSubset& subset = KeyframeSubset());

  // The loaded keyframe file's name and size (empty / 0 for a database
  // never loaded).
  const std::string& keyframes_file() const { return keyframes_file_; }
  uint64_t keyframes_bytes() const { return keyframes_bytes_; }

  static constexpr const char* kManifestFile = "manifest.json";
  // Name of the keyframe file whose header checksum is `checksum`.
  static std::string KeyframesFileName(uint64_t checksum);
  // Whether `name` is a keyframe file name of any generation (or version 1's
  // "keyframes.bin").
  static bool IsKeyframesFileName(const std::string& name);

 private:
  void DecodeKeyframeFile(std::shared_ptr<const MappedFile> file, const std::string& shown,
                          const LoadOptions& options);
  void CopyOnWrite();
  // Throws CorruptDatabase unless keyframe `index`'s features are checked
  // (checking them if they are not yet).
  void EnsureChecked(size_t index) const {
    if (lazy_ != nullptr && !FeaturesChecked(index)) CheckFeatures(index);
  }
  void CheckFeatures(size_t index) const;
  // Reads keyframe `index`'s descriptor rows (with `rows`), then its keypoint
  // records (with `records`) from the file into *buffer, unchecked, and
  // returns where the records start in *buffer (the rows' size).
  size_t ReadBlocks(size_t index, bool rows, bool records, std::vector<uint8_t>* buffer) const;
  // ReadBlocks for a use: when the keyframe is not checked yet both blocks
  // are read and checked (CorruptDatabase), then flagged.
  size_t ReadFeatures(size_t index, bool rows, bool records, std::vector<uint8_t>* buffer) const;
  // Why keyframe `index`'s features, given their compact keypoint records
  // and descriptor rows, are impossible (to follow "keyframe ID"), or "".
  std::string FeatureProblem(size_t index, const char* records, const uint8_t* rows) const;
  void EnsureWholeImageChecked() const;
  const cv::KeyPoint* KeypointData() const {
    return mapping_ ? mapped_keypoints_ : keypoints_.data();
  }
  const uint8_t* DescriptorData() const {
    return mapping_ ? mapped_descriptors_ : descriptors_.data();
  }

  FeatureType feature_type_ = FeatureType::kOrb;
  int descriptor_bytes_ = 32;
  int whole_image_dims_ = 0;
  std::vector<Keyframe> keyframes_;
  std::unordered_map<int32_t, int> index_of_id_;  // keyframe id -> index
  // Keyframe i owns feature rows [row_offset_[i], row_offset_[i] +
  // feature_count_[i]) of the keypoint and descriptor arrays (the file's,
  // when mapped); SURF: the first positive_count_[i] have Laplacian +1.
  std::vector<uint64_t> row_offset_;
  std::vector<uint32_t> feature_count_;
  std::vector<uint32_t> positive_count_;
  size_t num_features_ = 0;
  // Owned storage (built or grown databases).
  std::vector<cv::KeyPoint> keypoints_;
  std::vector<uint8_t> descriptors_;
  std::vector<int8_t> whole_image_;  // size() * whole_image_dims_
  // A loaded database uses its keypoints and descriptors in place in the
  // memory-mapped file; the first AddKeyframe copies them (copy on write).
  // Keypoints are cv::KeyPoint records (version 2) or compact records
  // (version 3, after the section's preamble).
  std::shared_ptr<const MappedFile> mapping_;
  const cv::KeyPoint* mapped_keypoints_ = nullptr;
  const char* mapped_compact_keypoints_ = nullptr;
  // What checks a version 3 file's features on first use (shared by
  // copies, which share the mapping); nullptr when everything is checked.
  struct LazyCheck;
  std::shared_ptr<LazyCheck> lazy_;
  uint32_t file_format_version_ = 0;
  const uint8_t* mapped_descriptors_ = nullptr;
  bool read_features_ = false;  // LoadOptions::read_features
  // The whole file's rows in place (a subset's are copied into whole_image_).
  const int8_t* mapped_whole_image_ = nullptr;
  // A subset's: every row of the file it was loaded from (checked at the
  // load), and their number.
  const int8_t* file_whole_image_ = nullptr;
  size_t file_whole_image_rows_ = 0;
  bool has_features_ = true;
  nlohmann::json info_ = nlohmann::json::object();
  KeyframeSubset subset_;
  size_t keyframes_in_file_ = 0;
  std::string keyframes_file_;
  uint64_t keyframes_bytes_ = 0;
};

}  // namespace placedb
