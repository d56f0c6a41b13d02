// Sequence-consistent recognition (sequence.h).
#include "placedb/query/sequence.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "placedb/query/order.h"
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
    t.Number("sequence_whole_image_weight", PLACEDB_MEMBER(O, whole_image_weight),
             OptionRange::Closed(0, 1000),
             "sequence over the whole map: a keyframe's evidence adds this times its standardised "
             "whole-image similarity (0: each frame's ranked keyframes alone)",
             kCallers)
        .absent = 0.0;
    t.Number("sequence_contrast_window", PLACEDB_MEMBER(O, contrast_window),
             OptionRange::Closed(0, 100000),
             "sequence over the whole map: standardise over this many keyframes on each side "
             "(SeqSLAM's local contrast enhancement; 0: over the whole map)",
             kCallers)
        .absent = int64_t{0};
    t.Number("sequence_hub_frames", PLACEDB_MEMBER(O, hub_frames), OptionRange::Closed(0, 100000),
             "sequence over the whole map: a keyframe's whole-image evidence is less its running "
             "mean over about this many frames (a keyframe like every frame gains nothing; 0: off)",
             kCallers)
        .absent = int64_t{50};
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
  const bool timed =
      !keyframes.empty() && std::all_of(keyframes.begin(), keyframes.end(),
                                        [](const Keyframe& k) { return k.timestamp >= 0.0; });
  std::vector<size_t> sorted(keyframes.size());
  for (size_t i = 0; i < sorted.size(); ++i) sorted[i] = i;
  std::stable_sort(sorted.begin(), sorted.end(), [&](size_t x, size_t y) {
    const Keyframe& a = keyframes[x];
    const Keyframe& b = keyframes[y];
    if (timed && a.timestamp != b.timestamp) return a.timestamp < b.timestamp;
    return a.id < b.id;
  });
  order_.clear();
  order_.reserve(keyframes.size());
  position_.clear();
  table_position_.assign(keyframes.size(), 0);
  for (size_t i = 0; i < sorted.size(); ++i) {
    order_.push_back(keyframes[sorted[i]]);
    table_position_[sorted[i]] = static_cast<int32_t>(i);
    if (!position_.emplace(order_[i].id, static_cast<int32_t>(i)).second) {
      PLACEDB_THROW_INVALID("the keyframe table holds keyframe ", order_[i].id, " twice");
    }
  }
  Reset();
}

void SequenceMatcher::Reset() {
  frames_.clear();
  hub_.clear();
}

std::vector<double> StandardisedAlongMap(const std::vector<double>& values, int window) {
  const size_t n = values.size();
  std::vector<double> sum(n + 1, 0.0), squares(n + 1, 0.0), count(n + 1, 0.0);
  for (size_t p = 0; p < n; ++p) {
    const bool valid = std::isfinite(values[p]);
    const double v = valid ? values[p] : 0.0;
    sum[p + 1] = sum[p] + v;
    squares[p + 1] = squares[p] + v * v;
    count[p + 1] = count[p] + (valid ? 1.0 : 0.0);
  }
  std::vector<double> out(n, 0.0);
  const auto w = static_cast<size_t>(std::max(0, window));
  for (size_t p = 0; p < n; ++p) {
    if (!std::isfinite(values[p])) continue;
    const size_t lo = w > 0 && p > w ? p - w : 0;
    const size_t hi = w > 0 ? std::min(n, p + w + 1) : n;
    const double c = count[hi] - count[lo];
    if (c < 2) continue;
    const double mean = (sum[hi] - sum[lo]) / c;
    const double var = (squares[hi] - squares[lo]) / c - mean * mean;
    // A flat neighbourhood (every value equal) says nothing.
    if (var > 1e-12) out[p] = (values[p] - mean) / std::sqrt(var);
  }
  return out;
}

namespace {

// A frame's local evidence: its ranked keyframes' positions and scores, by
// position, each once. `features_only`: the scores less their whole-image
// bonus (inliers when verified, else matches), for a search that counts
// the whole-image similarity itself.
std::vector<std::pair<int32_t, double>> LocalEvidence(
    const QueryResult& frame, const std::unordered_map<int32_t, int32_t>& position,
    double match_weight, size_t most, bool features_only) {
  std::vector<std::pair<int32_t, double>> entries;
  for (const RankedKeyframe& r : frame.ranked) {
    if (entries.size() == most) break;
    const auto it = position.find(r.keyframe_id);
    if (it == position.end()) continue;
    const double score = features_only ? query_order::FeatureScore(r) : r.score;
    entries.emplace_back(it->second,
                         std::max(0.0, score) + match_weight * std::max(0, r.num_matches));
  }
  std::sort(entries.begin(), entries.end());
  entries.erase(std::unique(entries.begin(), entries.end(),
                            [](const auto& a, const auto& b) { return a.first == b.first; }),
                entries.end());
  return entries;
}

}  // namespace

QueryResult SequenceMatcher::Feed(QueryResult frame) {
  FrameEvidence evidence;
  evidence.entries =
      LocalEvidence(frame, position_, options_.match_weight, kMaxEvidencePerFrame, false);
  frames_.push_front(std::move(evidence));
  while (frames_.size() > static_cast<size_t>(options_.length)) frames_.pop_back();
  return Decide(std::move(frame));
}

QueryResult SequenceMatcher::Feed(QueryResult frame, const std::vector<float>& similarities) {
  if (similarities.empty() || options_.whole_image_weight == 0) return Feed(std::move(frame));
  const size_t n = order_.size();
  if (similarities.size() != n) {
    PLACEDB_THROW_INVALID("whole-image similarities for ", similarities.size(),
                          " keyframes, the sequence's table has ", n);
  }
  FrameEvidence evidence;
  // The frame's whole-image bonus is counted below, over the whole map.
  evidence.entries =
      LocalEvidence(frame, position_, options_.match_weight, kMaxEvidencePerFrame, true);
  // The similarities by position, standardised over the map (or over a
  // window of keyframes around each), NaN left out (0 evidence).
  std::vector<double> value(n, std::numeric_limits<double>::quiet_NaN());
  for (size_t t = 0; t < n; ++t) value[static_cast<size_t>(table_position_[t])] = similarities[t];
  const std::vector<double> z = StandardisedAlongMap(value, options_.contrast_window);
  evidence.dense.resize(n);
  for (size_t p = 0; p < n; ++p)
    evidence.dense[p] = static_cast<float>(options_.whole_image_weight * z[p]);
  // Less each keyframe's running mean over about hub_frames frames: a
  // keyframe like every frame (snow, a tunnel, a bland wall) gains nothing.
  if (options_.hub_frames > 0) {
    if (hub_.size() != n) hub_.assign(n, 0.0f);
    const auto a = static_cast<float>(1.0 / static_cast<double>(options_.hub_frames));
    for (size_t p = 0; p < n; ++p) {
      const float z = evidence.dense[p];
      evidence.dense[p] = z - hub_[p];
      hub_[p] += a * (z - hub_[p]);
    }
  }
  for (const auto& [p, score] : evidence.entries) evidence.dense[static_cast<size_t>(p)] += score;
  frames_.push_front(std::move(evidence));
  while (frames_.size() > static_cast<size_t>(options_.length)) frames_.pop_back();
  return Decide(std::move(frame));
}

QueryResult SequenceMatcher::Decide(QueryResult frame) {
  const size_t h = frames_.size();
  const int64_t n = static_cast<int64_t>(order_.size());
  const bool dense = std::any_of(frames_.begin(), frames_.end(),
                                 [](const FrameEvidence& f) { return !f.dense.empty(); });

  // Offsets round(v k) per velocity and frame age, shared by both directions
  // of a path so that an end found from a position leads back to it.
  std::vector<int64_t> offset(velocities_.size() * h);
  for (size_t vi = 0; vi < velocities_.size(); ++vi) {
    for (size_t k = 0; k < h; ++k) {
      offset[vi * h + k] =
          static_cast<int64_t>(std::lround(velocities_[vi] * static_cast<double>(k)));
    }
  }
  const double mid = 0.5 * (options_.min_velocity + options_.max_velocity);
  double best_sum = -std::numeric_limits<double>::infinity();
  int64_t best_end = -1;
  size_t best_v = 0, best_used = 0;
  // The best path: the largest sum; ties: the lower end position, then the
  // velocity nearer the middle of the range, then the slower.
  auto consider = [&](int64_t j, size_t vi, double sum, size_t used) {
    const bool better =
        sum > best_sum ||
        (sum == best_sum &&
         (j < best_end || (j == best_end && std::abs(velocities_[vi] - mid) <
                                                std::abs(velocities_[best_v] - mid))));
    if (best_end < 0 || better) {
      best_sum = sum;
      best_end = j;
      best_v = vi;
      best_used = used;
    }
  };
  const size_t m0 = std::min(h, static_cast<size_t>(options_.min_length));
  if (dense) {
    // Every end x velocity. Over the whole map every keyframe has
    // standardised evidence in every frame, and a path's newest m frames are
    // compared by their sum over sqrt(m) (what a sum of m independent
    // standard scores is scaled by): a short path of chance highs does not
    // beat a long consistent one. Row by row, so that the work is h x
    // velocities passes over the map.
    std::vector<std::vector<float>> materialised;
    std::vector<const float*> rows(h);
    for (size_t k = 0; k < h; ++k) {
      if (!frames_[k].dense.empty()) {
        rows[k] = frames_[k].dense.data();
        continue;
      }
      materialised.emplace_back(static_cast<size_t>(n), 0.0f);  // a frame fed without similarities
      for (const auto& [p, score] : frames_[k].entries)
        materialised.back()[static_cast<size_t>(p)] = static_cast<float>(score);
      rows[k] = materialised.back().data();
    }
    // Single precision: sums of at most 100 frames of evidence, and twice the
    // values per vector instruction.
    std::vector<float> prefix(static_cast<size_t>(n)), rank(static_cast<size_t>(n));
    for (size_t vi = 0; vi < velocities_.size(); ++vi) {
      std::fill(prefix.begin(), prefix.end(), 0.0f);
      std::fill(rank.begin(), rank.end(), -std::numeric_limits<float>::infinity());
      for (size_t k = 0; k < h; ++k) {
        // End j was at j - off k frames back: inside the map for j in [lo, hi).
        const int64_t off = offset[vi * h + k];
        const int64_t lo = std::max<int64_t>(0, off), hi = std::min<int64_t>(n, n + off);
        const float* row = rows[k];
        for (int64_t j = lo; j < hi; ++j) prefix[static_cast<size_t>(j)] += row[j - off];
        if (k + 1 < m0) continue;
        const float scale = 1.0f / std::sqrt(static_cast<float>(k + 1));
        float* rk = rank.data();
        const float* pf = prefix.data();
        for (size_t j = 0; j < static_cast<size_t>(n); ++j) {  // vectorised: a max
          const float r = pf[j] * scale;
          rk[j] = rk[j] < r ? r : rk[j];
        }
      }
      // This velocity's best end (the first of equal ones), then the rule.
      if (n == 0) continue;
      size_t top = 0;
      for (size_t j = 1; j < static_cast<size_t>(n); ++j) {
        if (rank[j] > rank[top]) top = j;
      }
      // Its frames used: the first m whose rank is the best, walked again
      // with the same sums.
      float sum = 0.0f;
      size_t used = h;
      for (size_t k = 0; k < h; ++k) {
        const int64_t p = static_cast<int64_t>(top) - offset[vi * h + k];
        if (p >= 0 && p < n) sum += rows[k][p];
        if (k + 1 >= m0 && sum * (1.0f / std::sqrt(static_cast<float>(k + 1))) == rank[top]) {
          used = k + 1;
          break;
        }
      }
      consider(static_cast<int64_t>(top), vi, rank[top], used);
    }
  } else {
    // The ends some held frame's evidence reaches; each once per velocity.
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
    for (const auto& [j, vi] : ends) {
      // The path's best mean over its newest m frames, m from min_length up:
      // a path that began when the camera came back to a mapped stretch is
      // not diluted by the frames before.
      double sum = -1.0, prefix = 0.0;
      size_t used = h;
      for (size_t k = 0; k < h; ++k) {
        prefix += frames_[k].Lookup(j - offset[vi * h + k]);
        if (k + 1 >= m0 && prefix / static_cast<double>(k + 1) * static_cast<double>(h) > sum) {
          sum = prefix / static_cast<double>(k + 1) * static_cast<double>(h);
          used = k + 1;
        }
      }
      consider(j, vi, sum, used);
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
    // The path's mean evidence per frame over the frames it used.
    s.score = dense ? best_sum / std::sqrt(static_cast<double>(best_used))
                    : best_sum / static_cast<double>(h);
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
