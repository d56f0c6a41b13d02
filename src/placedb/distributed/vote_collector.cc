#include "placedb/distributed/vote_collector.h"

#include <algorithm>

#include "placedb/util/check.h"
#include "placedb/util/options.h"

namespace placedb {

const char* VoteStatusName(VoteStatus status) {
  switch (status) {
    case VoteStatus::kAccepted:
      return "accepted";
    case VoteStatus::kDuplicate:
      return "duplicate";
    case VoteStatus::kUnknownPartition:
      return "unknown partition";
    case VoteStatus::kLate:
      return "late";
  }
  return "?";
}

VoteCollector::VoteCollector(const VoteOptions& options) : options_(options) {
  PLACEDB_CHECK_OPTIONS(options_);
}

bool VoteCollector::Stale(uint64_t seq) {
  if (!any_answered_ || seq > newest_answered_ || pending_.count(seq)) return false;
  if (newest_answered_ - seq > static_cast<uint64_t>(options_.max_pending)) {
    pending_.clear();  // the feed started over
    any_answered_ = false;
    return false;
  }
  return true;
}

void VoteCollector::OnFrame(uint64_t frame_seq, double now_ms) {
  if (Stale(frame_seq)) return;
  pending_.try_emplace(frame_seq, Pending{now_ms, {}});
}

VoteStatus VoteCollector::OnPartial(uint64_t frame_seq, int partition, const QueryResult& partial,
                                    double now_ms) {
  if (partition < 0 || partition >= options_.num_partitions) return VoteStatus::kUnknownPartition;
  if (Stale(frame_seq)) return VoteStatus::kLate;
  auto [it, inserted] = pending_.try_emplace(frame_seq, Pending{now_ms, {}});
  if (!it->second.partials.emplace(partition, partial).second) return VoteStatus::kDuplicate;
  return VoteStatus::kAccepted;
}

FrameAnswer VoteCollector::Answer(uint64_t seq, Pending&& p, double now_ms) const {
  FrameAnswer a;
  a.frame_seq = seq;
  std::vector<QueryResult> parts;
  for (auto& [partition, result] : p.partials) {
    a.answered.push_back(partition);
    parts.push_back(std::move(result));
  }
  for (int i = 0; i < options_.num_partitions; ++i) {
    if (!p.partials.count(i)) a.missing.push_back(i);
  }
  a.result = MergeQueryResults(parts, options_.query);
  a.waited_ms = now_ms - p.first_seen_ms;
  return a;
}

std::vector<FrameAnswer> VoteCollector::Poll(double now_ms) {
  std::vector<FrameAnswer> ready;
  std::vector<uint64_t> done;
  const size_t excess = pending_.size() > static_cast<size_t>(options_.max_pending)
                            ? pending_.size() - static_cast<size_t>(options_.max_pending)
                            : 0;
  size_t evicted = 0;
  for (auto& [seq, p] : pending_) {
    const bool complete = static_cast<int>(p.partials.size()) == options_.num_partitions;
    const bool expired = now_ms - p.first_seen_ms >= options_.deadline_ms;
    const bool evict = evicted < excess;  // the oldest first (map order)
    if (complete || expired || evict) {
      if (evict) ++evicted;
      done.push_back(seq);
    }
  }
  for (const uint64_t seq : done) {
    auto node = pending_.extract(seq);
    ready.push_back(Answer(seq, std::move(node.mapped()), now_ms));
  }
  for (const uint64_t seq : done) {
    newest_answered_ = any_answered_ ? std::max(newest_answered_, seq) : seq;
    any_answered_ = true;
  }
  return ready;
}

}  // namespace placedb
