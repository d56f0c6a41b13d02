// The session API: one open database with the extractor its queries need.
// Every client (the CLI, eval, ROS nodes, Python) opens and queries a
// database through this class.
//
//   placedb::PlaceDatabase db = placedb::PlaceDatabase::Open("office.db");
//   placedb::QueryResult r = db.Query(cv::imread("frame.png"));
//   if (const placedb::RankedKeyframe* best = r.best()) use(best->keyframe_id, best->pose);
//
// Query methods are const and thread-safe.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "placedb/feature/extractor.h"
#include "placedb/index/builder.h"
#include "placedb/index/database.h"
#include "placedb/index/keyframe_subset.h"
#include "placedb/index/query.h"

namespace placedb {

class ThreadPool;

struct OpenOptions {
  // Which keyframes to open: all (default), partition i of N, or an id list.
  KeyframeSubset subset;
  // When set, a database of another feature type is an error naming both.
  std::optional<FeatureType> expected_features;
  // Threads each query uses for matching and verification; 0 = one per core.
  // Range [0, 1024]. Default 1.
  int threads = 1;

  std::string Check() const;
};

class PlaceDatabase {
 public:
  // Opens the database directory `dir`: loads the keyframes (or the subset),
  // reads every build setting from the manifest and checks it (the feature
  // options must also agree with the stored descriptors), and creates the
  // extractor queries need. Errors: std::runtime_error for a missing or
  // damaged database, std::invalid_argument for bad options or a feature type
  // other than options.expected_features.
  static PlaceDatabase Open(const std::string& dir, const OpenOptions& options = OpenOptions());

  PlaceDatabase(PlaceDatabase&&) noexcept;
  PlaceDatabase& operator=(PlaceDatabase&&) noexcept;
  ~PlaceDatabase();

  const std::string& directory() const;
  const Database& database() const;
  // The manifest: every build setting, counts, sizes, creation info.
  const nlohmann::json& manifest() const;
  const BuildOptions& build_options() const;
  const ExtractorOptions& extractor_options() const;
  FeatureType feature_type() const;
  size_t size() const;
  bool empty() const { return size() == 0; }
  // The keyframe with this id, or nullptr.
  const Keyframe* FindKeyframe(int32_t id) const;
  // Path of a keyframe's stored PNG ("" when the database keeps none).
  std::string StoredImagePath(const Keyframe& keyframe) const;
  // The pool queries run on (nullptr for one thread).
  ThreadPool* pool() const;

  // The query features of an image, as Query(image) computes them: an 8-bit
  // gray, BGR or BGRA frame, full and uncropped. An empty image or another
  // depth is std::invalid_argument.
  FeatureSet Extract(const cv::Mat& image) const;

  // Where was this frame taken? retrieve -> match -> verify -> decide.
  QueryResult Query(const cv::Mat& image, const QueryOptions& options = QueryOptions()) const;
  // The same for features computed elsewhere (another node, another process).
  // They are validated against the database (std::invalid_argument).
  QueryResult Query(const FeatureSet& features, const QueryOptions& options = QueryOptions()) const;
  // Both restricted to keyframe indices `keyframes` (a partition, a cluster,
  // bag-of-words candidates): only those are examined.
  QueryResult QueryAmong(const cv::Mat& image, const std::vector<uint32_t>& keyframes,
                         const QueryOptions& options = QueryOptions()) const;
  QueryResult QueryAmong(const FeatureSet& features, const std::vector<uint32_t>& keyframes,
                         const QueryOptions& options = QueryOptions()) const;

 private:
  struct Impl;
  explicit PlaceDatabase(std::unique_ptr<Impl> impl);
  QueryResult Run(const FeatureSet& features, const std::vector<uint32_t>* among,
                  const QueryOptions& options, double extract_ms) const;
  std::unique_ptr<Impl> impl_;
};

}  // namespace placedb
