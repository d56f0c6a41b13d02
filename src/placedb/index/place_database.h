// The session API: one open database with the extractor its queries need.
// Every client (the CLI, eval, ROS nodes, Python) opens and queries a
// database through this class.
//
//   placedb::PlaceDatabase db = placedb::PlaceDatabase::Open("office.db");
//   placedb::QueryResult r = db.Query(cv::imread("frame.png"));
//   if (const placedb::RankedKeyframe* best = r.best()) use(best->keyframe_id, best->pose);
//
// Query methods are const and thread-safe. Online mapping (Add, Remove,
// Save) may run while queries do: a query sees the keyframes as they were
// when it started, and an addition becomes visible all at once.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "placedb/feature/extractor.h"
#include "placedb/index/builder.h"
#include "placedb/index/clusters.h"
#include "placedb/index/database.h"
#include "placedb/index/growing_bow_index.h"
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
  // How keyframes are grouped for cluster search (made when the database
  // opens, from the keyframes' poses or their order).
  ClusterOptions clusters;

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
  // The bag-of-words index (nullptr when the database was built without
  // one: then bow search is an error naming the rebuild flag).
  const GrowingBowIndex* bow_index() const;
  // The spatial-locality clusters of the opened keyframes.
  const ClusterSet& clusters() const;

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

  // Why keyframe `keyframe_id` matched `features` (or did not): the match
  // and verify stages on it alone, every match kept (MatchKeyframe). For
  // pictures and diagnostics. std::invalid_argument for an unknown id.
  MatchDetail Explain(const FeatureSet& features, int32_t keyframe_id,
                      const QueryOptions& options = QueryOptions()) const;

  // ---- Online mapping: the robot keeps mapping while it localises ----------
  // Adds a keyframe made from `image` (8-bit gray, BGR or BGRA) as the
  // database was built: crop, resize, features, the stored PNG when the
  // database keeps images. `frame` gives its id (>= 1, new), timestamp, pose
  // and source path. The work is done before the keyframe is published:
  // queries wait only while it is appended, and see it whole or not at all.
  // Writers are serialised. std::invalid_argument for a taken id, a bad
  // image or a session opened on a subset (open the whole database).
  void Add(const Frame& frame, const cv::Mat& image);
  // The same with features computed elsewhere (in the stored image's frame).
  void Add(Keyframe keyframe, const FeatureSet& features);
  // Takes keyframe `id` out of every later answer; false when there is no
  // such keyframe. Its storage is reclaimed by Save.
  bool Remove(int32_t id);
  // Keyframes added or removed since the database was opened or saved.
  size_t num_pending_changes() const;
  // Writes the keyframes as they are now back to directory(), crash-safely
  // (the previous generation stays until the new manifest is in place),
  // rebuilding the bag-of-words index with the same vocabulary. The session
  // then reads the saved generation: it answers as a reopened database does.
  void Save();

 private:
  struct Impl;
  explicit PlaceDatabase(std::unique_ptr<Impl> impl);
  QueryResult Run(const FeatureSet& features, const std::vector<uint32_t>* among,
                  const QueryOptions& options, double extract_ms) const;
  std::unique_ptr<Impl> impl_;
};

}  // namespace placedb
