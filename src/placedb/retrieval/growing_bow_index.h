// A bag-of-words index that grows with online mapping: the stored BowIndex
// (used in place from its file) for the keyframes it was built on, and the
// bags of words of the keyframes added since, searched as one. A keyframe's
// score is BowScore with the query either way (the same terms in the same
// order), so a database saved and reopened after online additions retrieves
// exactly the same candidates.
#pragma once

#include <cstdint>
#include <unordered_map>
#include <vector>

#include "placedb/retrieval/bow_index.h"

namespace placedb {

class GrowingBowIndex {
 public:
  explicit GrowingBowIndex(BowIndex base) : base_(std::move(base)) {}

  const BowIndex& base() const { return base_; }
  const Vocabulary& vocabulary() const { return base_.vocabulary(); }
  // Keyframes: the stored index's, then the added ones (database order).
  size_t size() const { return base_.size() + added_.size(); }
  size_t num_added() const { return added_.size(); }

  BowVector Transform(const DescriptorBlock& rows, std::vector<uint32_t>* nodes = nullptr) const {
    return base_.Transform(rows, nodes);
  }
  // The bag of words of the next keyframe (index size()) and the
  // direct-level node of each of its feature rows (Transform's `nodes`).
  void Append(BowVector words, std::vector<uint32_t> nodes);
  // The direct-level node of each feature row of keyframe `index` (<
  // size()), as BowIndex::DirectNodes.
  std::vector<uint32_t> DirectNodes(uint32_t index) const;

  // The best `max_results` keyframes by BowScore with `query`, best first
  // (ties: the lower index), over the stored and the added keyframes; with
  // `among` (sorted, unique indices < size()), only those.
  // Under `deadline`, as BowIndex::Query: stops once it has passed and sets
  // *stopped (the added keyframes are then not scored).
  // `excluded`: as BowIndex::Query's, over all size() keyframes.
  std::vector<BowIndex::Scored> Query(const BowVector& query, size_t max_results,
                                      const std::vector<uint32_t>* among,
                                      const Deadline& deadline = Deadline(),
                                      bool* stopped = nullptr,
                                      const uint8_t* excluded = nullptr) const;
  // The same for `among`, scoring each of them in full instead of walking
  // the inverted file; Query does this when `among` is a small share of the
  // database (a cluster and its neighbours).
  std::vector<BowIndex::Scored> ScoreEach(const BowVector& query, size_t max_results,
                                          const std::vector<uint32_t>& among,
                                          const uint8_t* excluded = nullptr) const;

 private:
  // `among` smaller than size() / this is scored keyframe by keyframe.
  static constexpr size_t kDirectScoreFactor = 64;

  BowIndex base_;
  std::vector<BowVector> added_;
  std::vector<std::vector<uint32_t>> added_nodes_;
  // word -> the added keyframes (offsets into added_) that have it, ascending.
  std::unordered_map<uint32_t, std::vector<uint32_t>> added_postings_;
};

}  // namespace placedb
