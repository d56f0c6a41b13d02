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

#include "placedb/storage/database.h"
#include "placedb/retrieval/retriever.h"
#include "placedb/match/geometric_verification.h"
#include "placedb/match/ratio_matcher.h"
#include "placedb/util/pose.h"

namespace placedb {

class ClusterSet;
class GrowingBowIndex;
class ThreadPool;

// Where the robot probably is, for cluster search: the last answer's
// keyframe, or a pose in the map frame (the keyframe wins when both are set).
struct QueryPrior {
  // Id of a keyframe near the query (the previous frame's answer); 0: none.
  // Range [0, 2^31). An id not in the database is no prior.
  int32_t keyframe_id = 0;
  std::optional<Pose> pose;

  bool empty() const { return keyframe_id == 0 && !pose; }
  std::string Check() const;
};

struct QueryOptions {
  // Length of the ranked list returned. Range [1, 10000]. Default 5.
  int top_k = 5;
  // Keyframes with fewer matches than this are not ranked. Range [1, 100000].
  // Default 1.
  int min_matches = 1;
  // Retrieve stage: which keyframes are examined.
  RetrievalOptions retrieval;
  // Match stage: ratio test, one-to-one, sparse-keyframe guard.
  MatchOptions match;
  // Verify stage: USAC on the best candidates; the inliers become the score.
  VerifyOptions verify;
  // Decide stage: the best keyframe is the answer when its score (inliers when
  // verified, else matches) is at least this; else "no match / new place".
  // Range [0, 100000]. Default 12.
  double min_score = 12.0;
  // Time budget of retrieve + match + verify, in milliseconds; 0 = none.
  // Candidates are examined best prior first until it runs out (at least
  // one is examined and verified), so a query is late by at most one
  // candidate's work; the result's coverage says how much was searched.
  // Range [0, 1e7]. Default 0.
  double deadline_ms = 0.0;
  // For cluster search: where the robot probably is. Default none.
  QueryPrior prior;

  std::string Check() const;
  // The options a partition (thread, process, worker node) runs with so that
  // MergeQueryResults can rebuild the whole database's answer exactly: the
  // ranked list keeps every verified candidate, not just the top k.
  QueryOptions ForPartition() const;
};

// One keyframe of an answer.
struct RankedKeyframe {
  int32_t keyframe_id = 0;
  // What the ranking uses: num_inliers when verified, else num_matches.
  double score = 0.0;
  int num_matches = 0;   // matches that passed the match stage
  int num_inliers = -1;  // geometric inliers; -1 when not verified
  bool verified() const { return num_inliers >= 0; }
  std::optional<Pose> pose;  // the keyframe's pose (its map coordinates), when known
  double timestamp = -1.0;   // of the keyframe's source frame, -1 when unknown
  std::string source;        // the keyframe's source image
  std::string stored_image;  // its stored PNG (database dir joined), "" when none

  bool operator==(const RankedKeyframe& o) const;
};

// Milliseconds spent in each stage of one query.
struct StageTimes {
  double extract_ms = 0.0;  // query feature extraction (0 when features were given)
  double retrieve_ms = 0.0;
  double match_ms = 0.0;
  double verify_ms = 0.0;
  double total_ms = 0.0;
};

struct QueryResult {
  // Best first, at most top_k: with verification, the verified candidates by
  // inliers (then matches, then lower id); without, by matches (then id).
  std::vector<RankedKeyframe> ranked;
  // The decision: ranked[0] is the answer when true; false means "no match /
  // new place" (nothing ranked, or the best score is below min_score).
  bool matched = false;
  int num_query_features = 0;
  size_t num_keyframes = 0;  // in the database (partition, restriction) searched
  size_t num_examined = 0;   // keyframes the match stage compared
  size_t num_verified = 0;   // keyframes the verify stage ran on
  // num_examined / num_keyframes (0 for an empty database).
  double coverage = 0.0;
  // The deadline stopped the match or verify stage early.
  bool deadline_reached = false;
  // How the candidates were found: "exhaustive", "bow", "cluster" (the
  // prior's clusters were enough), "cluster+fallback" (the local answer was
  // weak and the rest of the database was searched too), "cluster+global"
  // (no usable prior: a global search).
  std::string search = "exhaustive";
  // cluster search: the prior's cluster, -1 when none.
  int cluster = -1;
  StageTimes times;

  // The answer, or nullptr for "no match".
  const RankedKeyframe* best() const { return matched ? &ranked.front() : nullptr; }
};

// JSON of a result (for the CLI, reports and the wire) and back. from_json
// validates everything and throws InvalidArgument naming the field (JSON from
// the wire is a caller's input).
void to_json(nlohmann::json& j, const QueryResult& r);
void from_json(const nlohmann::json& j, QueryResult& r);
void to_json(nlohmann::json& j, const RankedKeyframe& r);
void from_json(const nlohmann::json& j, RankedKeyframe& r);

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

// Why a keyframe matched: the match and verify stages of a query on one
// keyframe, with every match kept (for pictures and diagnostics).
struct MatchDetail {
  int32_t keyframe_id = 0;
  // The query's keypoints, in the order the matches' queryIdx refers to
  // (SURF: grouped by Laplacian sign, as the match stage sees them).
  std::vector<cv::KeyPoint> query_keypoints;
  // The keyframe's keypoints (trainIdx), in its original image and in its
  // stored (cropped, resized) image.
  std::vector<cv::Point2f> keyframe_points;
  std::vector<cv::Point2f> keyframe_stored_points;
  std::vector<cv::DMatch> matches;  // what passed the match stage
  bool verified = false;            // the verify stage ran
  int num_inliers = 0;
  std::vector<uint8_t> inliers;  // one per match when verified (1: inlier)
};

// The match and verify stages of `options` on keyframe `index` of `db`
// (verify when options.verify.enabled and at least min_matches matched): the
// same matches and inliers a query would find for it. Throws
// InvalidArgument for features `db` cannot match or a bad index.
MatchDetail MatchKeyframe(const Database& db, const FeatureSet& query, size_t index,
                          const QueryOptions& options);

// The voting step. `parts` are results of disjoint partitions of one database,
// each computed with options.ForPartition(); the merge ranks and decides as
// QueryDatabase on the whole database would (the same ranked list and
// decision). Counts add up; stage times are the slowest part's (the parts
// run in parallel). Throws InvalidArgument when a keyframe appears in
// two parts or verified and unverified entries are mixed.
QueryResult MergeQueryResults(const std::vector<QueryResult>& parts, const QueryOptions& options);

}  // namespace placedb
