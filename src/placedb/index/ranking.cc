#include "placedb/index/ranking.h"

#include <algorithm>
#include <unordered_map>

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

std::vector<ScoredKeyframe> MergeRankedLists(const std::vector<std::vector<ScoredKeyframe>>& lists,
                                             int k) {
  std::unordered_map<int32_t, double> best;
  for (const auto& list : lists) {
    for (const ScoredKeyframe& s : list) {
      auto [it, inserted] = best.emplace(s.keyframe_id, s.score);
      if (!inserted && s.score > it->second) it->second = s.score;
    }
  }
  std::vector<ScoredKeyframe> merged;
  merged.reserve(best.size());
  for (const auto& [id, score] : best) merged.push_back({id, score});
  return TopK(std::move(merged), k);
}

}  // namespace placedb
