// Plain ranked lists of {keyframe id, score}: the form baselines and
// comparisons use. (The query pipeline's answer is QueryResult, query.h,
// and its voting step MergeQueryResults.)
#pragma once

#include <cstdint>
#include <ostream>
#include <vector>

namespace placedb {

struct ScoredKeyframe {
  int32_t keyframe_id = 0;  // the keyframe's id (its frame id)
  double score = 0.0;       // higher is better (good matches, inliers...)

  bool operator==(const ScoredKeyframe& o) const {
    return keyframe_id == o.keyframe_id && score == o.score;
  }
};

// For test failure messages: "{id: score}".
inline std::ostream& operator<<(std::ostream& os, const ScoredKeyframe& s) {
  return os << "{" << s.keyframe_id << ": " << s.score << "}";
}

// Ranking order: higher score first; equal scores by lower keyframe id, so
// every ranking is deterministic whatever produced it.
bool RanksBefore(const ScoredKeyframe& a, const ScoredKeyframe& b);

// The best `k` of `list` in ranking order (partial_sort); k <= 0 keeps all.
std::vector<ScoredKeyframe> TopK(std::vector<ScoredKeyframe> list, int k);

}  // namespace placedb
