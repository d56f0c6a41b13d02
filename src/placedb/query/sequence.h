// Sequence-consistent recognition: evidence from the last frames of a stream
// accumulated along paths through the database's keyframe order (SeqSLAM's
// idea, Milford & Wyeth 2012, on placedb's own per-frame answers).
//
// A caller queries each frame as usual and feeds the frame's QueryResult to a
// SequenceMatcher, in the order the frames were taken (causal: only past
// frames count). The matcher keeps the last `length` frames' evidence and
// answers with the keyframe at the end of the best path, with the path's own
// score for the decide stage:
//
//  - The keyframe order is by timestamp when every keyframe has one, else by
//    id. A keyframe's position is its index in that order.
//  - A frame's evidence is its ranked list (at most kMaxEvidencePerFrame
//    entries): keyframe -> score + match_weight x matches in this frame
//    (score: inliers when verified, else matches; fused with the
//    whole-image channel when it is on). A keyframe the frame did not rank has evidence 0 in that frame.
//    So with exhaustive search "every keyframe" means the frame's best
//    `top_k`, and with bag-of-words the candidates that reached the ranked
//    list; a caller that wants denser evidence raises `top_k`.
//  - A path ends at position j in the newest frame and moves v keyframes per
//    frame: k frames earlier it was at j - round(v k). v takes
//    `velocity_steps` values evenly from `min_velocity` to `max_velocity`.
//    Its score is its best mean evidence over its newest m frames, m from
//    min_length to the h frames held (h <= length).
//  - Only ends some frame's evidence can reach are scored: for every held
//    frame's ranked position p (k frames back) and velocity v, j = p +
//    round(v k). The work per frame is bounded by length^2 x
//    kMaxEvidencePerFrame x velocity_steps, whatever the database's size.
//  - The decision: with at least 2 frames held and a best path scoring at
//    least `min_score`, the sequence decides: its end keyframe is the answer
//    (first in `ranked`, added if the frame did not rank it).
//    Otherwise, when the frame's own answer is matched, the frame decides (a
//    jump the path has not followed yet); otherwise, with 2 frames or more,
//    the path's end is ranked first but not matched. QueryResult::decided_by
//    says which decided and QueryResult::sequence holds the path and the
//    frame's own answer.
//
// Reset() forgets the frames (a new run, a relocalisation, a jump in time).
// Keyframes added to the database after the matcher was made are unknown to
// it (their evidence is ignored) until SetKeyframes.
#pragma once

#include <cstdint>
#include <deque>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "placedb/query/result.h"
#include "placedb/storage/keyframe.h"
#include "placedb/util/option_table.h"

namespace placedb {

struct SequenceOptions {
  // Frames of evidence, the newest included. Range [1, 100]. Default 15:
  // the longest that keeps the loop's sequence recall in the docs' "hard
  // places" table (a longer path gains under change on a steady route and
  // loses where the camera turns; docs' "places that change").
  int length = 15;
  // A path's score is its best mean evidence over its newest m frames, m
  // from min_length to the frames held: a path the camera joined a few
  // frames ago (coming back to a mapped stretch) is not diluted by the
  // frames before. Range [1, 100], at most `length`. Default 2.
  int min_length = 2;
  // Keyframes the camera moves per frame: paths are tried for velocity_steps
  // values in [min_velocity, max_velocity]. Negative: driving the map
  // backwards. Range [-100, 100] each, min <= max. Default [0, 2].
  double min_velocity = 0.0;
  double max_velocity = 2.0;
  // Range [1, 101]. Default 9 (steps of 0.25).
  int velocity_steps = 9;
  // A keyframe's evidence in a frame: its score (inliers when verified, else
  // matches) plus match_weight x its matches, so that a keyframe whose
  // matches verification could not confirm (tiny frames: too few points
  // for a model) still counts. Range [0, 100]. Default 1.
  double match_weight = 1.0;
  // Decide: the best path's mean evidence per frame must reach this. Range
  // [0, 100000]. Default 5.
  double min_score = 5.0;
  // Over the whole map (Feed with similarities): a keyframe's evidence in a
  // frame adds this times its whole-image similarity standardised over the
  // map's keyframes for that frame (minus their mean, over their standard
  // deviation), so that every keyframe has evidence in every frame, as in
  // SeqSLAM's difference matrix; 0: each frame's ranked keyframes alone.
  // Range [0, 1000]. Default 10 (a keyframe 3 standard deviations above the
  // map counts as 30 inliers; docs' "places that change" table has what it
  // gives).
  double whole_image_weight = 10.0;
  // Over the whole map: the standardisation is over the `contrast_window`
  // keyframes on each side of a keyframe (SeqSLAM's local contrast
  // enhancement) instead of the whole map when above 0. Range [0, 100000].
  // Default 0.
  int contrast_window = 0;
  // Over the whole map: a keyframe's standardised whole-image evidence is
  // less its exponential running mean over about `hub_frames` frames (since
  // the last Reset), so that a keyframe like every frame (a hub: snow, a
  // tunnel, a bland wall) gains nothing from it. A camera that stands still
  // for about this many frames sees its own keyframe's evidence fade the
  // same way. 0: off. Range [0, 100000]. Default 50 (over three default lengths).
  int hub_frames = 50;

  static const OptionTable<SequenceOptions>& Table();
  std::string Check() const;
};

// Each finite value minus the mean, over the (population) standard
// deviation, of the finite values within `window` places on each side (the
// whole vector when window is 0): SeqSLAM's local contrast enhancement.
// NaN values, places with fewer than 2 finite values around them and flat
// neighbourhoods give 0.
std::vector<double> StandardisedAlongMap(const std::vector<double>& values, int window);

class SequenceMatcher {
 public:
  static constexpr size_t kMaxEvidencePerFrame = 64;

  // `keyframes`: the database's keyframe table (PlaceDatabase::keyframes()).
  SequenceMatcher(const std::vector<Keyframe>& keyframes, const SequenceOptions& options);

  // Adds `frame` (a single-frame answer) as the newest frame and returns it
  // with the sequence's decision.
  QueryResult Feed(QueryResult frame);
  // The same over the whole map: `similarities` holds the frame's
  // whole-image similarity to every keyframe of the table, in the table's
  // order (PlaceDatabase::WholeImageSimilarities), num_keyframes() values
  // (NaN for a keyframe to leave out, a removed one). Every keyframe is
  // every frame's evidence (see whole_image_weight), so every path through
  // the map is scored: the work per frame is num_keyframes() x
  // velocity_steps x length, and the frames held take length x
  // num_keyframes() floats. A frame fed without similarities while others
  // had them counts as a frame whose whole-image evidence is 0.
  // Empty `similarities` (a database without the channel), or
  // whole_image_weight 0: Feed(frame). InvalidArgument for another number
  // of values.
  QueryResult Feed(QueryResult frame, const std::vector<float>& similarities);

  // Forgets every frame.
  void Reset();
  // A new keyframe table (after additions or removals); resets.
  void SetKeyframes(const std::vector<Keyframe>& keyframes);

  size_t frames_held() const { return frames_.size(); }
  size_t num_keyframes() const { return order_.size(); }
  const SequenceOptions& options() const { return options_; }

 private:
  struct FrameEvidence {
    std::vector<std::pair<int32_t, double>> entries;  // (position, score), by position
    std::vector<float> dense;  // whole map: the evidence by position, entries included
    double Lookup(int64_t position) const;
  };
  QueryResult Decide(QueryResult frame);

  SequenceOptions options_;
  std::vector<Keyframe> order_;                    // keyframes in sequence order (no features)
  std::unordered_map<int32_t, int32_t> position_;  // keyframe id -> index in order_
  std::vector<int32_t> table_position_;            // table index -> index in order_
  std::vector<double> velocities_;
  std::deque<FrameEvidence> frames_;  // newest first
  std::vector<float> hub_;            // by position: the running means of hub_frames
};

}  // namespace placedb
