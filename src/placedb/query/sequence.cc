// Sequence-consistent recognition (sequence.h).
#include "placedb/query/sequence.h"

#include <algorithm>
#include <cmath>

#include "placedb/util/check.h"

namespace placedb {

const OptionTable<SequenceOptions>& SequenceOptions::Table() {
  static const OptionTable<SequenceOptions> table = [] {
    using O = SequenceOptions;
    OptionTable<O> t("sequence options");
    t.Number("sequence_length", PLACEDB_MEMBER(O, length), OptionRange::Closed(1, 100),
             "sequence: frames of evidence, the newest included (SeqSLAM's ds)", kCallers);
    t.Number("sequence_min_length", PLACEDB_MEMBER(O, min_length), OptionRange::Closed(1, 100),
             "sequence: a path's score is its best mean over its newest m frames, m from this "
             "up to `sequence_length`",
             kCallers);
    t.Number("sequence_min_velocity", PLACEDB_MEMBER(O, min_velocity),
             OptionRange::Closed(-100, 100),
             "sequence: slowest keyframes per frame a path moves (negative: backwards)", kCallers);
    t.Number("sequence_max_velocity", PLACEDB_MEMBER(O, max_velocity),
             OptionRange::Closed(-100, 100), "sequence: fastest keyframes per frame", kCallers);
    t.Number("sequence_velocity_steps", PLACEDB_MEMBER(O, velocity_steps),
             OptionRange::Closed(1, 101),
             "sequence: velocities tried, evenly from the slowest to the fastest", kCallers);
    t.Number("sequence_match_weight", PLACEDB_MEMBER(O, match_weight), OptionRange::Closed(0, 100),
             "sequence: a keyframe's evidence in a frame is its score plus this times its "
             "matches",
             kCallers);
    t.Number("sequence_min_score", PLACEDB_MEMBER(O, min_score), OptionRange::Closed(0, 100000),
             "sequence: the best path is the answer when its mean score per frame is at least "
             "this",
             kCallers);
    t.Rule([](const O& o) -> std::string {
      if (o.min_length > o.length) return "`sequence_min_length` is above `sequence_length`";
      if (o.min_velocity > o.max_velocity)
        return "`sequence_min_velocity` is above `sequence_max_velocity`";
      return "";
    });
    return t;
  }();
  return table;
}

std::string SequenceOptions::Check() const { return Table().Check(*this); }

double SequenceMatcher::FrameEvidence::Lookup(int64_t position) const {
  const auto it =
      std::lower_bound(entries.begin(), entries.end(), position,
                       [](const std::pair<int32_t, double>& e, int64_t p) { return e.first < p; });
  return it != entries.end() && it->first == position ? it->second : 0.0;
}

SequenceMatcher::SequenceMatcher(const std::vector<Keyframe>& keyframes,
                                 const SequenceOptions& options)
    : options_(options) {
  PLACEDB_CHECK_OPTIONS(options_);
  const int n = options_.velocity_steps;
  for (int i = 0; i < n; ++i) {
    velocities_.push_back(n == 1
                              ? options_.min_velocity
                              : options_.min_velocity +
                                    (options_.max_velocity - options_.min_velocity) * i / (n - 1));
  }
  SetKeyframes(keyframes);
}

void SequenceMatcher::SetKeyframes(const std::vector<Keyframe>& keyframes) {
  order_ = keyframes;
  const bool timed =
      !order_.empty() && std::all_of(order_.begin(), order_.end(),
                                     [](const Keyframe& k) { return k.timestamp >= 0.0; });
  std::stable_sort(order_.begin(), order_.end(), [timed](const Keyframe& a, const Keyframe& b) {
    if (timed && a.timestamp != b.timestamp) return a.timestamp < b.timestamp;
    return a.id < b.id;
  });
  position_.clear();
  for (size_t i = 0; i < order_.size(); ++i) {
    if (!position_.emplace(order_[i].id, static_cast<int32_t>(i)).second) {
      PLACEDB_THROW_INVALID("the keyframe table holds keyframe ", order_[i].id, " twice");
    }
  }
  Reset();
}

void SequenceMatcher::Reset() { frames_.clear(); }

QueryResult SequenceMatcher::Feed(QueryResult frame) {
  // This frame's evidence: its ranked keyframes' positions and scores.
  FrameEvidence evidence;
  for (const RankedKeyframe& r : frame.ranked) {
    if (evidence.entries.size() == kMaxEvidencePerFrame) break;
    const auto it = position_.find(r.keyframe_id);
    if (it == position_.end()) continue;
    evidence.entries.emplace_back(
        it->second, std::max(0.0, r.score) + options_.match_weight * std::max(0, r.num_matches));
  }
  std::sort(evidence.entries.begin(), evidence.entries.end());
  evidence.entries.erase(
      std::unique(evidence.entries.begin(), evidence.entries.end(),
                  [](const auto& a, const auto& b) { return a.first == b.first; }),
      evidence.entries.end());
  frames_.push_front(std::move(evidence));
  while (frames_.size() > static_cast<size_t>(options_.length)) frames_.pop_back();
  const size_t h = frames_.size();
  const int64_t n = static_cast<int64_t>(order_.size());

  // Offsets round(v k) per velocity and frame age, shared by both directions
  // of a path so that an end found from a position leads back to it.
  std::vector<int64_t> offset(velocities_.size() * h);
  for (size_t vi = 0; vi < velocities_.size(); ++vi) {
    for (size_t k = 0; k < h; ++k) {
      offset[vi * h + k] =
          static_cast<int64_t>(std::lround(velocities_[vi] * static_cast<double>(k)));
    }
  }
  // Ends some held frame's evidence reaches; scored once each per velocity.
  std::vector<std::pair<int64_t, size_t>> ends;  // (end position, velocity index)
  for (size_t k = 0; k < h; ++k) {
    for (const auto& e : frames_[k].entries) {
      for (size_t vi = 0; vi < velocities_.size(); ++vi) {
        const int64_t j = e.first + offset[vi * h + k];
        if (j >= 0 && j < n) ends.emplace_back(j, vi);
      }
    }
  }
  std::sort(ends.begin(), ends.end());
  ends.erase(std::unique(ends.begin(), ends.end()), ends.end());
  const double mid = 0.5 * (options_.min_velocity + options_.max_velocity);
  double best_sum = -1.0;
  int64_t best_end = -1;
  size_t best_v = 0, best_used = 0;
  for (const auto& [j, vi] : ends) {
    // The path's best mean over its newest m frames, m from min_length up:
    // a path that began when the camera came back to a mapped stretch is
    // not diluted by the frames before.
    double sum = -1.0, prefix = 0.0;
    const size_t m0 = std::min(h, static_cast<size_t>(options_.min_length));
    size_t used = h;
    for (size_t k = 0; k < h; ++k) {
      prefix += frames_[k].Lookup(j - offset[vi * h + k]);
      if (k + 1 >= m0 && prefix / static_cast<double>(k + 1) * static_cast<double>(h) > sum) {
        sum = prefix / static_cast<double>(k + 1) * static_cast<double>(h);
        used = k + 1;
      }
    }
    // Ties: the lower end position (ends are visited in position order),
    // then the velocity nearer the middle of the range.
    if (sum > best_sum || (sum == best_sum && j == best_end &&
                           std::abs(velocities_[vi] - mid) < std::abs(velocities_[best_v] - mid))) {
      best_sum = sum;
      best_end = j;
      best_v = vi;
      best_used = used;
    }
  }

  SequenceEvidence s;
  s.frames = static_cast<int>(best_end >= 0 ? best_used : h);
  if (!frame.ranked.empty()) {
    s.frame_keyframe_id = frame.ranked.front().keyframe_id;
    s.frame_score = frame.ranked.front().score;
  }
  s.frame_matched = frame.matched;
  if (best_end >= 0) {
    s.keyframe_id = order_[static_cast<size_t>(best_end)].id;
    s.score = best_sum / static_cast<double>(h);
    s.velocity = velocities_[best_v];
  }
  frame.sequence = s;
  frame.decided_by = "frame";
  if (h < 2 || best_end < 0) return frame;
  const bool path_matched = s.score >= options_.min_score;
  // A confident frame the path does not agree with: the frame answers (a
  // jump the path has not followed yet).
  if (!path_matched && frame.matched) return frame;
  auto it = std::find_if(frame.ranked.begin(), frame.ranked.end(),
                         [&](const RankedKeyframe& r) { return r.keyframe_id == s.keyframe_id; });
  if (it != frame.ranked.end()) {
    std::rotate(frame.ranked.begin(), it, it + 1);
  } else {
    const Keyframe& k = order_[static_cast<size_t>(best_end)];
    RankedKeyframe r;
    r.keyframe_id = k.id;
    r.score = 0.0;  // this frame did not rank it
    r.pose = k.pose;
    r.timestamp = k.timestamp;
    r.source = k.source;
    // The list keeps its length (top_k): the frame's last entry makes room.
    if (!frame.ranked.empty()) frame.ranked.pop_back();
    frame.ranked.insert(frame.ranked.begin(), std::move(r));
  }
  frame.matched = path_matched;
  frame.decided_by = "sequence";
  return frame;
}

}  // namespace placedb
