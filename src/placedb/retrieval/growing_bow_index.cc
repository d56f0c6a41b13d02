#include "placedb/retrieval/growing_bow_index.h"

#include <algorithm>

#include "placedb/util/check.h"

namespace placedb {
namespace {

// Best score first, ties by the lower index; the first `max_results`.
void SortAndCut(std::vector<BowIndex::Scored>* list, size_t max_results) {
  std::sort(list->begin(), list->end(), [](const BowIndex::Scored& a, const BowIndex::Scored& b) {
    return a.score != b.score ? a.score > b.score : a.index < b.index;
  });
  if (list->size() > max_results) list->resize(max_results);
}

}  // namespace

std::vector<BowIndex::Scored> GrowingBowIndex::ScoreEach(const BowVector& query, size_t max_results,
                                                         const std::vector<uint32_t>& among,
                                                         const uint8_t* excluded) const {
  if (!among.empty() && among.back() >= size()) {
    PLACEDB_THROW_INVALID("keyframe index ", among.back(), " is out of range (the index holds ",
                          size(), ")");
  }
  const uint32_t base = static_cast<uint32_t>(base_.size());
  std::vector<BowIndex::Scored> out;
  for (const uint32_t index : among) {
    if (excluded != nullptr && excluded[index]) continue;
    const double score =
        BowScore(query, index < base ? base_.KeyframeVector(index) : added_[index - base]);
    if (score > 0.0) out.push_back({index, score});
  }
  SortAndCut(&out, max_results);
  return out;
}

void GrowingBowIndex::Append(BowVector words, std::vector<uint32_t> nodes) {
  const uint32_t offset = static_cast<uint32_t>(added_.size());
  for (const uint32_t w : words.words) added_postings_[w].push_back(offset);
  added_.push_back(std::move(words));
  added_nodes_.push_back(std::move(nodes));
}

std::vector<uint32_t> GrowingBowIndex::DirectNodes(uint32_t index) const {
  const uint32_t base = static_cast<uint32_t>(base_.size());
  if (index < base) return base_.DirectNodes(index);
  if (index - base >= added_nodes_.size()) {
    PLACEDB_THROW_INVALID("keyframe index ", index, " is out of range (the index holds ", size(),
                          ")");
  }
  return added_nodes_[index - base];
}

std::vector<BowIndex::Scored> GrowingBowIndex::Query(const BowVector& query, size_t max_results,
                                                     const std::vector<uint32_t>* among,
                                                     const Deadline& deadline, bool* stopped,
                                                     const uint8_t* excluded) const {
  const uint32_t base = static_cast<uint32_t>(base_.size());
  // A few keyframes (a cluster and its neighbours) are scored one by one:
  // cheaper than walking the query's postings over the whole database. The
  // scores are the same either way (BowIndex::Query's are BowScore's).
  if (among != nullptr && among->size() * kDirectScoreFactor < size())
    return ScoreEach(query, max_results, *among, excluded);
  if (added_.empty()) return base_.Query(query, max_results, among, deadline, stopped, excluded);
  std::vector<uint32_t> base_among, added_among;
  if (among != nullptr) {
    if (!among->empty() && among->back() >= size()) {
      PLACEDB_THROW_INVALID("keyframe index ", among->back(), " is out of range (the index holds ",
                            size(), ")");
    }
    const auto split = std::lower_bound(among->begin(), among->end(), base);
    base_among.assign(among->begin(), split);
    added_among.assign(split, among->end());
  }
  bool base_stopped = false;
  std::vector<BowIndex::Scored> out =
      base_.Query(query, max_results, among != nullptr ? &base_among : nullptr, deadline,
                  &base_stopped, excluded);
  if (base_stopped) {
    if (stopped != nullptr) *stopped = true;
    return out;
  }
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
    if (excluded != nullptr && excluded[index]) continue;
    if (among != nullptr && !std::binary_search(added_among.begin(), added_among.end(), index))
      continue;
    const double score = BowScore(query, added_[offset]);
    if (score > 0.0) out.push_back({index, score});
  }
  SortAndCut(&out, max_results);
  return out;
}

}  // namespace placedb
