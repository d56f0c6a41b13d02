// A query's options and its answer: the ranked keyframes, the decision
// ("no match / new place" or the best keyframe and its pose), the stage
// times and counts; the voting merge of partial answers; the answer's JSON
// (part of the public face, placedb/placedb.h; the stages that compute it
// are query/query.h).
#pragma once

#include <cstdint>
#include <opencv2/core/types.hpp>
#include <optional>
#include <string>
#include <vector>

#include "placedb/match/options.h"
#include "placedb/retrieval/options.h"
#include "placedb/util/option_table.h"
#include "placedb/util/pose.h"

namespace placedb {

// Where the robot probably is, for cluster search: the last answer's
// keyframe, or a pose in the map frame (the keyframe wins when both are set).
struct QueryPrior {
  // Id of a keyframe near the query (the previous frame's answer); 0: none.
  // Range [0, 2^31). An id not in the database is no prior.
  int32_t keyframe_id = 0;
  std::optional<Pose> pose;

  bool empty() const { return keyframe_id == 0 && !pose; }
  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<QueryPrior>& Table();
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
  // The whole-image channel (databases that have it, queries from images):
  // a keyframe's score is its local-feature score (inliers, or matches when
  // unverified) plus whole_image_weight x max(0, z - whole_image_floor),
  // where z is its whole-image similarity standardised over every keyframe
  // of the database for this query (minus their mean, over their standard
  // deviation; RankedKeyframe::whole_image_z); the match stage keeps
  // keyframes by matches plus the same bonus. Standardised, the bonus means
  // the same for every descriptor, camera and map size, and only a keyframe
  // that stands out from the map gains: where local features hold they
  // still decide. Range [0, 10000]. Default 10 (a keyframe 5 deviations
  // above the map's mean counts as 20 inliers); 0: the channel does not
  // score. Chosen on docs' "places that change" table.
  double whole_image_weight = 10.0;
  // The standardised similarity below which the channel adds nothing: what
  // unrelated keyframes reach. Range [0, 100]. Default 3 (three standard
  // deviations).
  double whole_image_floor = 3.0;
  // Retrieval other than exhaustive also passes on the keyframes most
  // similar by whole-image descriptor (searched exhaustively: it is tiny),
  // so that a place whose local features changed is still examined. Range
  // [0, 1000]. Default 20; 0: none.
  int whole_image_candidates = 20;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<QueryOptions>& Table();
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
  // The cosine similarity of the query's and the keyframe's whole-image
  // descriptors (feature/whole_image.h), in [-1, 1], when both have one and
  // the channel ran (whole_image_weight or whole_image_candidates above 0).
  std::optional<double> whole_image;
  // The same standardised over the database's keyframes for this query
  // (deviations above their mean; 0 when they do not vary), with
  // whole_image. The score includes whole_image_weight x max(0,
  // whole_image_z - whole_image_floor).
  std::optional<double> whole_image_z;

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

// The sequence's part of an answer (query/sequence.h): the best path through
// the keyframe order over the last frames, and the frame's own answer.
struct SequenceEvidence {
  int32_t keyframe_id = 0;  // the path's end: the sequence's answer (0: none)
  double score = 0.0;       // the path's mean evidence per frame
  int frames = 0;           // frames the path's score is the mean over
  double velocity = 0.0;    // keyframes per frame
  // The frame's own (single-frame) answer: its best keyframe (0: none), its
  // score and decision.
  int32_t frame_keyframe_id = 0;
  double frame_score = 0.0;
  bool frame_matched = false;

  bool operator==(const SequenceEvidence& o) const;
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
  // Which answered: "frame" (this frame's own query) or "sequence" (a
  // SequenceMatcher's path: its end is ranked first and `matched` is the
  // path's decision). `sequence` is set when a SequenceMatcher fed on it.
  std::string decided_by = "frame";
  std::optional<SequenceEvidence> sequence;

  // The answer, or nullptr for "no match".
  const RankedKeyframe* best() const { return matched ? &ranked.front() : nullptr; }
  // The score the decision was made on: the path's when the sequence
  // answered, else the first keyframe's (0 when none).
  double decision_score() const;
};

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

// The voting step. `parts` are results of disjoint partitions of one database,
// each computed with options.ForPartition(); the merge ranks and decides as
// QueryDatabase on the whole database would (the same ranked list and
// decision). Counts add up; stage times are the slowest part's (the parts
// run in parallel). Throws InvalidArgument when a keyframe appears in
// two parts or verified and unverified entries are mixed.
QueryResult MergeQueryResults(const std::vector<QueryResult>& parts, const QueryOptions& options);

// ---- Bag-of-words search split over partitions, exactly ----------------------
// MergeQueryResults is exact for exhaustive search, but a bag-of-words part
// would pick its own best candidates, which are not the whole database's.
// Two rounds make it exact:
//   1. every part sends its shortlist (ShortlistDatabase, query.h): its best
//      bow_candidates by bag-of-words score with their guided match counts,
//      and its whole_image_candidates most similar keyframes;
//   2. the voter merges them (MergeShortlists) into the candidates the whole
//      database's search would examine; every part matches and verifies its
//      own share of them (exhaustive search among them, with
//      options.ForPartition()), and MergeQueryResults merges the answers.
// The merged answer ranks the same keyframes with the same matches, inliers
// and scores as the whole database's bag-of-words search (tested;
// scale_bench's partition row). The parts must hold one database: entries
// carry the keyframe's index in it, which breaks ties.
struct ShortlistEntry {
  uint32_t index = 0;  // the keyframe's index in the database
  int32_t keyframe_id = 0;
  double score = 0.0;  // bag-of-words score, or whole-image similarity
  int guided = -1;     // guided matches; -1: not counted
  bool operator==(const ShortlistEntry& o) const;
};
struct Shortlist {
  std::vector<ShortlistEntry> bow;          // best score first (ties: lower index)
  std::vector<ShortlistEntry> whole_image;  // most similar first (ties: lower index)
  bool deadline_reached = false;            // the part's scoring was cut short
  double retrieve_ms = 0.0;
};
// The candidates the whole database's bag-of-words search examines, from
// every part's shortlist (computed with the same options): the best
// bow_candidates of the union by score, cut to guided_candidates by guided
// count as the bow search does, then the whole_image_candidates most similar
// of the union that are not among them. InvalidArgument when a keyframe
// comes from two parts with different values, or an entry is malformed.
std::vector<ShortlistEntry> MergeShortlists(const std::vector<Shortlist>& parts,
                                            const QueryOptions& options);

// The answer as the library's JSON text (`indent` -1: one line), and back:
// QueryResultFromJson validates every field (InvalidArgument naming it), for
// answers received over the wire. The CLI's --json, eval's records and the
// ROS voter's answers are this JSON.
std::string QueryResultToJson(const QueryResult& result, int indent = -1);
QueryResult QueryResultFromJson(const std::string& json);
// One ranked keyframe's JSON, as it appears in the answer's.
std::string RankedKeyframeToJson(const RankedKeyframe& keyframe, int indent = -1);
// A shortlist's JSON ({"bow": [[index, keyframe_id, score, guided], ...],
// "whole_image": [...], "deadline_reached", "retrieve_ms"}), and back, every
// field validated, as for answers.
std::string ShortlistToJson(const Shortlist& shortlist, int indent = -1);
Shortlist ShortlistFromJson(const std::string& json);

}  // namespace placedb
