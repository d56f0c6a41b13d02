#include "placedb/distributed/partition_worker.h"

#include <utility>

#include "placedb/util/check.h"

namespace placedb {

BowPartitionWorker::BowPartitionWorker(const PlaceDatabase& db, const KeyframeSubset& partition,
                                       const QueryOptions& options, size_t max_pending)
    : db_(db), partition_(partition), options_(options), max_pending_(max_pending) {
  PLACEDB_CHECK_OPTIONS(options_);
  if (partition_.kind != KeyframeSubset::Kind::kPartition) {
    PLACEDB_THROW_INVALID("a partition worker needs a partition I/N (not ", partition_.Describe(),
                          ")");
  }
  const std::string bad = partition_.Check();
  if (!bad.empty()) PLACEDB_THROW_INVALID("invalid partition: ", bad);
  if (options_.retrieval.method != RetrievalMethod::kBow) {
    PLACEDB_THROW_INVALID("two rounds are for bag-of-words search, not ",
                          RetrievalMethodName(options_.retrieval.method));
  }
  if (!db_.subset().all()) {
    PLACEDB_THROW_INVALID(
        "a partition worker needs a session on the whole database (this one is "
        "on ",
        db_.subset().Describe(), ")");
  }
  if (max_pending_ == 0) PLACEDB_THROW_INVALID("max_pending must be at least 1");
  share_ = options_.ForPartition();
  share_.retrieval.method = RetrievalMethod::kExhaustive;
  ids_ = db_.keyframe_ids();
  for (size_t i = 0; i < ids_.size(); ++i) {
    if (InPartition(i, ids_.size(), partition_.part, partition_.num_parts, partition_.scheme))
      mine_.push_back(ids_[i]);
  }
}

Shortlist BowPartitionWorker::MakeShortlist(uint64_t frame_seq, FeatureSet features) {
  Shortlist shortlist = db_.BowShortlist(features, &mine_, options_);
  features_[frame_seq] = std::move(features);
  while (features_.size() > max_pending_) features_.erase(features_.begin());
  return shortlist;
}

QueryResult BowPartitionWorker::Answer(uint64_t frame_seq,
                                       const std::vector<ShortlistEntry>& candidates) {
  const auto found = features_.find(frame_seq);
  if (found == features_.end()) {
    PLACEDB_THROW_INVALID("frame ", frame_seq,
                          ": no features kept for it (not shortlisted here, answered already, or "
                          "forgotten after ",
                          max_pending_, " newer frames)");
  }
  std::vector<int32_t> share;
  for (const ShortlistEntry& c : candidates) {
    if (c.index >= ids_.size() || ids_[c.index] != c.keyframe_id) {
      PLACEDB_THROW_INVALID("candidate keyframe ", c.keyframe_id, " at index ", c.index,
                            " is not this database's (", ids_.size(), " keyframes)");
    }
    if (InPartition(c.index, ids_.size(), partition_.part, partition_.num_parts, partition_.scheme))
      share.push_back(c.keyframe_id);
  }
  const FeatureSet features = std::move(found->second);
  features_.erase(found);
  // With no candidate of its own the answer is empty, but it is sent: the
  // voter then knows this partition has answered.
  return db_.QueryAmong(features, share, share_);
}

}  // namespace placedb
