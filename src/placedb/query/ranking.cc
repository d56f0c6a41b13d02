#include "placedb/query/ranking.h"

#include <algorithm>

namespace placedb {

bool RanksBefore(const ScoredKeyframe& a, const ScoredKeyframe& b) {
  if (a.score != b.score) return a.score > b.score;
  return a.keyframe_id < b.keyframe_id;
}

std::vector<ScoredKeyframe> TopK(std::vector<ScoredKeyframe> list, int k) {
  const size_t keep = k <= 0 ? list.size() : std::min(list.size(), static_cast<size_t>(k));
  std::partial_sort(list.begin(), list.begin() + keep, list.end(), RanksBefore);
  list.resize(keep);
  return list;
}

}  // namespace placedb
