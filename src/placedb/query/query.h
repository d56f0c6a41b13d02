// The query pipeline and its result:
//
//   retrieve (which keyframes; a Retriever) -> match (ratio test, one-to-one,
//   sparse-keyframe guard; MatchDescriptors) -> verify (USAC on the best
//   candidates' matches; VerifyMatches) -> decide (a score threshold gives
//   "no match / new place").
//
// QueryDatabase runs it on one Database (or a restriction of it), on one
// thread or a pool: the answer does not depend on the number of threads.
// MergeQueryResults is the voting step: it merges the partial results of
// disjoint partitions (threads, processes, ROS worker nodes) into the answer
// the whole database gives. Both are pure library code, tested without any
// transport; QueryResult converts to and from JSON for the wire and reports.
#pragma once

#include <atomic>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "placedb/match/geometric_verification.h"
#include "placedb/match/ratio_matcher.h"
#include "placedb/query/result.h"
#include "placedb/retrieval/retriever.h"
#include "placedb/storage/database.h"
#include "placedb/util/pose.h"

namespace placedb {

class ClusterSet;
class GrowingBowIndex;
class ThreadPool;

// JSON of a result (for the CLI, reports and the wire) and back. from_json
// validates everything and throws InvalidArgument naming the field (JSON from
// the wire is a caller's input).
void to_json(nlohmann::json& j, const QueryResult& r);
void from_json(const nlohmann::json& j, QueryResult& r);
void to_json(nlohmann::json& j, const RankedKeyframe& r);
void from_json(const nlohmann::json& j, RankedKeyframe& r);
void to_json(nlohmann::json& j, const Shortlist& s);
void from_json(const nlohmann::json& j, Shortlist& s);

// Throws InvalidArgument unless `features` can be matched against `db`:
// one descriptor row per keypoint, the database's descriptor type and width,
// contiguous rows, finite keypoints within the largest image (CheckKeypoints
// with an unknown size), finite SURF descriptor values.
void ValidateQueryFeatures(const FeatureSet& features, const Database& db);

// What one candidate's match and verify cost in recent queries under a
// deadline: a decaying maximum of each query's costliest candidate (each
// report lowers the old value by 2 % before taking the larger). A session
// keeps one, so that the retrieve stage stops early enough for the first
// candidate, which a query always examines, to end by the deadline.
// Thread-safe.
class CandidateCost {
 public:
  // Milliseconds; 0 until a query has reported.
  double Get() const { return ms_.load(std::memory_order_relaxed); }
  void Report(double worst_ms);

 private:
  std::atomic<double> ms_{0.0};
};

// Where and how QueryDatabase runs.
struct QueryContext {
  // Retrieve stage; nullptr: exhaustive.
  const Retriever* retriever = nullptr;
  // Restriction to these keyframe indices (a partition, a cluster, BoW
  // candidates); nullptr: all. Out-of-range indices are invalid input.
  const std::vector<uint32_t>* among = nullptr;
  // Keyframes left out of every stage (removed online): one byte per
  // keyframe of the database, 1 = left out, tested per candidate (and per
  // posting by the bag-of-words scoring); nullptr: none. `num_excluded` is
  // how many are set. The answer equals the one of a database without them.
  const std::vector<uint8_t>* excluded = nullptr;
  size_t num_excluded = 0;
  // Matching and verification spread over this pool; nullptr: this thread.
  ThreadPool* pool = nullptr;
  // The database's bag-of-words index (bow search; cluster search uses it
  // within and beyond the clusters when given); nullptr: none.
  const GrowingBowIndex* bow = nullptr;
  // Spatial-locality clusters (cluster search needs them); nullptr: none.
  const ClusterSet* clusters = nullptr;
  // Folder the keyframes' stored images are relative to ("": left relative).
  std::string image_dir;
  // Under a deadline: the session's estimate of one candidate's cost, which
  // the retrieve stage leaves free before the deadline (and which the query
  // updates); nullptr: none is left.
  CandidateCost* candidate_cost = nullptr;
  // The query's clock, when it started before QueryDatabase (a session
  // starts it before waiting for its lock): the deadline and total_ms count
  // from it. nullptr: they count from QueryDatabase's start.
  const Timer* clock = nullptr;
};

// Runs retrieve -> match -> verify -> decide for already-extracted features.
QueryResult QueryDatabase(const Database& db, const FeatureSet& query, const QueryOptions& options,
                          const QueryContext& context = QueryContext());

// Round 1 of a bag-of-words search split over partitions (result.h,
// MergeShortlists): the part's shortlist, the part being context.among (or
// the whole database). options.retrieval.method must be bow
// (InvalidArgument); the rest of `context` as for QueryDatabase.
Shortlist ShortlistDatabase(const Database& db, const FeatureSet& query,
                            const QueryOptions& options,
                            const QueryContext& context = QueryContext());

// The match and verify stages of `options` on keyframe `index` of `db`
// (verify when options.verify.enabled and at least min_matches matched): the
// same matches and inliers a query would find for it. Throws
// InvalidArgument for features `db` cannot match or a bad index.
MatchDetail MatchKeyframe(const Database& db, const FeatureSet& query, size_t index,
                          const QueryOptions& options);

}  // namespace placedb
