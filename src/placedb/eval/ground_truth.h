// Deciding, without looking, whether a retrieved keyframe is a correct match
// for a query: from a list of true matches (CSV) or from poses.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "placedb/dataset/frame.h"
#include "placedb/dataset/frame_source.h"
#include "placedb/dataset/match_truth.h"
#include "placedb/storage/keyframe.h"
#include "placedb/util/option_table.h"

namespace placedb {

struct PoseThresholds {
  // A keyframe is a correct match when its camera centre is within this
  // distance of the query's, metres. Default 0.5 (TUM scenes: a place is a
  // step or two).
  double max_distance_m = 0.5;
  // ... and its viewing direction within this angle of the query's, degrees.
  // Default 30 (views that share most of their content at room scale).
  double max_angle_deg = 30.0;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<PoseThresholds>& Table();
  std::string Check() const;
};

class GroundTruth {
 public:
  // Truth from a match list: query id -> ids of the true keyframes.
  static GroundTruth FromMatchList(MatchTruth truth);
  // Truth from poses: both the query and the keyframe must have a pose.
  static GroundTruth FromPoses(const PoseThresholds& thresholds);

  // Whether the query can be judged at all (listed / has a pose).
  bool HasTruth(const Frame& query) const;
  // Whether `keyframe` is a correct answer for `query`.
  bool IsCorrect(const Frame& query, const Keyframe& keyframe) const;
  // Whether the database holds at least one correct answer for `query`.
  bool AnyCorrectIn(const Frame& query, const std::vector<Keyframe>& keyframes) const;

  // Whether correctness comes from a match list (else from poses).
  bool IsMatchList() const { return list_.has_value(); }
  // Whether any of `keyframes` can ever be judged correct: a match list
  // names one of their ids; pose truth: one has a pose.
  bool CanJudgeAny(const std::vector<Keyframe>& keyframes) const;
  // Match list: the query and keyframe ids it names above `max_id` (sorted,
  // unique), ids no frame of the data can have. Poses: none.
  std::vector<int> IdsAbove(int max_id) const;

  // "match list" or "poses (0.5 m, 30 deg)".
  std::string Describe() const;

 private:
  std::optional<MatchTruth> list_;
  PoseThresholds thresholds_;
};

// How correctness is judged, as a command or a script gives it: a CSV of
// true matches (`truth`) or, without one, the query frames' poses.
struct GroundTruthOptions {
  // A CSV of true matches (query_id,keyframe ids); "" = poses decide.
  std::string truth;
  PoseThresholds poses;

  static const OptionTable<GroundTruthOptions>& Table();
  std::string Check() const;
};

// The ground truth for queries read from `queries`: the match list, or the
// poses, which an image folder lacks (InvalidArgument naming `truth`).
GroundTruth MakeGroundTruth(const GroundTruthOptions& options, const FrameSourceOptions& queries);

}  // namespace placedb
