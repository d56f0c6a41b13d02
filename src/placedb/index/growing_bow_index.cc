#include "placedb/index/growing_bow_index.h"

#include <algorithm>

#include "placedb/util/check.h"

namespace placedb {

void GrowingBowIndex::Append(BowVector words) {
  const uint32_t offset = static_cast<uint32_t>(added_.size());
  for (const uint32_t w : words.words) added_postings_[w].push_back(offset);
  added_.push_back(std::move(words));
}

std::vector<BowIndex::Scored> GrowingBowIndex::Query(const BowVector& query, size_t max_results,
                                                     const std::vector<uint32_t>* among) const {
  const uint32_t base = static_cast<uint32_t>(base_.size());
  if (added_.empty()) return base_.Query(query, max_results, among);
  std::vector<uint32_t> base_among, added_among;
  if (among != nullptr) {
    PLACEDB_CHECK(among->empty() || among->back() < size(), "keyframe index ", among->back(),
                  " is out of range");
    const auto split = std::lower_bound(among->begin(), among->end(), base);
    base_among.assign(among->begin(), split);
    added_among.assign(split, among->end());
  }
  std::vector<BowIndex::Scored> out =
      base_.Query(query, max_results, among != nullptr ? &base_among : nullptr);
  // The added keyframes that share a word with the query, scored in full.
  std::vector<uint32_t> touched;
  for (const uint32_t w : query.words) {
    const auto it = added_postings_.find(w);
    if (it != added_postings_.end())
      touched.insert(touched.end(), it->second.begin(), it->second.end());
  }
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  for (const uint32_t offset : touched) {
    const uint32_t index = base + offset;
    if (among != nullptr && !std::binary_search(added_among.begin(), added_among.end(), index))
      continue;
    const double score = BowScore(query, added_[offset]);
    if (score > 0.0) out.push_back({index, score});
  }
  auto better = [](const BowIndex::Scored& a, const BowIndex::Scored& b) {
    return a.score != b.score ? a.score > b.score : a.index < b.index;
  };
  std::sort(out.begin(), out.end(), better);
  if (out.size() > max_results) out.resize(max_results);
  return out;
}

}  // namespace placedb
