// Ranked lists of keyframes and the pure function that merges partial lists.
// The same merge serves partitions searched by threads and (later) by worker
// nodes: it is the voting step, tested without any transport.
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

// Merges partial top-k lists into the global top-k. A keyframe present in
// several lists keeps its highest score. When the partial lists cover
// disjoint keyframes and each is the top-k of its part, the result equals
// the top-k of the whole.
std::vector<ScoredKeyframe> MergeRankedLists(const std::vector<std::vector<ScoredKeyframe>>& lists,
                                             int k);

}  // namespace placedb
