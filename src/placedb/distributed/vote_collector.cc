#include "placedb/distributed/vote_collector.h"

#include <algorithm>

#include "placedb/query/order.h"
#include "placedb/session/place_database.h"
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
    case VoteStatus::kInconsistent:
      return "inconsistent";
    case VoteStatus::kUnexpected:
      return "unexpected";
  }
  return "?";
}

VoteCollector::VoteCollector(const VoteOptions& options) : options_(options) {
  PLACEDB_CHECK_OPTIONS(options_);
  two_rounds_ =
      options_.query.retrieval.method == RetrievalMethod::kBow && options_.num_partitions > 1;
}

bool VoteCollector::Stale(uint64_t seq, double now_ms) {
  if (pending_.count(seq)) return false;
  if (answered_.count(seq)) return true;
  if (any_answered_ && seq < newest_answered_ &&
      newest_answered_ - seq > static_cast<uint64_t>(options_.max_pending)) {
    // Far below every number answered: the source started over (one that
    // does not announce its frames, or whose announcement comes later).
    StartOver(now_ms, /*keep_unannounced=*/false);
    ++stats_.runs;
  }
  return false;
}

void VoteCollector::StartOver(double now_ms, bool keep_unannounced) {
  for (auto it = pending_.begin(); it != pending_.end();) {
    if (keep_unannounced && !it->second.announced) {
      ++it;
      continue;
    }
    flushed_.push_back(Answer(it->first, std::move(it->second), now_ms));
    it = pending_.erase(it);
  }
  answered_.clear();
  any_answered_ = false;
  any_announced_ = false;
}

VoteStatus VoteCollector::OnFrame(uint64_t frame_seq, double now_ms, const std::string& run) {
  const bool new_run = run != run_ || (any_announced_ && frame_seq < newest_announced_);
  if (new_run) {
    // The old run's announced frames are answered under its id; frames seen
    // only through partial results may be the new run's (its announcement
    // travels on another connection than the workers' results).
    StartOver(now_ms, /*keep_unannounced=*/true);
    run_ = run;
  }
  if (new_run || stats_.runs == 0) ++stats_.runs;
  newest_announced_ = any_announced_ ? std::max(newest_announced_, frame_seq) : frame_seq;
  any_announced_ = true;
  if (Stale(frame_seq, now_ms)) return VoteStatus::kLate;
  Pending& p = pending_.try_emplace(frame_seq, Pending(now_ms)).first->second;
  p.announced = true;
  return VoteStatus::kAccepted;
}

VoteStatus VoteCollector::OnPartial(uint64_t frame_seq, int partition, const QueryResult& partial,
                                    double now_ms) {
  if (partition < 0 || partition >= options_.num_partitions) return VoteStatus::kUnknownPartition;
  if (Stale(frame_seq, now_ms)) return VoteStatus::kLate;
  if (two_rounds_) {
    // Only the partitions the candidates were merged from answer, after them.
    const auto found = pending_.find(frame_seq);
    if (found == pending_.end() || !found->second.candidates_out ||
        !found->second.merged.count(partition))
      return VoteStatus::kUnexpected;
  }
  auto [it, inserted] = pending_.try_emplace(frame_seq, Pending(now_ms));
  Pending& p = it->second;
  if (p.partials.count(partition)) return VoteStatus::kDuplicate;
  // What MergeQueryResults refuses is refused here, so that Poll never fails:
  // each keyframe once across the frame's results, verified as the vote is.
  // Each score as the vote's options make it (the whole-image bonus
  // included), so that a worker run with other options cannot tilt the merge.
  std::set<int32_t> ids;
  for (const RankedKeyframe& r : partial.ranked) {
    if (r.verified() != options_.query.verify.enabled || !ids.insert(r.keyframe_id).second)
      return VoteStatus::kInconsistent;
    if (r.score != query_order::FusedScore(r, options_.query)) return VoteStatus::kInconsistent;
  }
  for (const auto& [other, result] : p.partials) {
    for (const RankedKeyframe& r : result.ranked) {
      if (ids.count(r.keyframe_id)) return VoteStatus::kInconsistent;
    }
  }
  p.partials.emplace(partition, partial);
  return VoteStatus::kAccepted;
}

VoteStatus VoteCollector::OnShortlist(uint64_t frame_seq, int partition, const Shortlist& shortlist,
                                      double now_ms) {
  if (!two_rounds_) return VoteStatus::kUnexpected;
  if (partition < 0 || partition >= options_.num_partitions) return VoteStatus::kUnknownPartition;
  if (Stale(frame_seq, now_ms)) return VoteStatus::kLate;
  Pending& p = pending_.try_emplace(frame_seq, Pending(now_ms)).first->second;
  if (p.candidates_out) return VoteStatus::kLate;
  if (p.shortlists.count(partition)) return VoteStatus::kDuplicate;
  // What MergeShortlists refuses is refused here, so that PollCandidates
  // never fails: a keyframe offered twice (by this partition or another)
  // with other values.
  for (const auto list : {&Shortlist::bow, &Shortlist::whole_image}) {
    std::map<uint32_t, const ShortlistEntry*> seen;
    for (const auto& [other, s] : p.shortlists) {
      for (const ShortlistEntry& e : s.*list) seen.emplace(e.index, &e);
    }
    for (const ShortlistEntry& e : shortlist.*list) {
      const auto [at, inserted] = seen.emplace(e.index, &e);
      if (!inserted && !(*at->second == e)) return VoteStatus::kInconsistent;
    }
  }
  p.shortlists.emplace(partition, shortlist);
  return VoteStatus::kAccepted;
}

std::vector<FrameCandidates> VoteCollector::PollCandidates(double now_ms) {
  std::vector<FrameCandidates> out;
  if (!two_rounds_) return out;
  for (auto& [seq, p] : pending_) {
    if (p.candidates_out || p.shortlists.empty()) continue;
    const bool all = static_cast<int>(p.shortlists.size()) == options_.num_partitions;
    // Half the deadline for the shortlists, half for the answers.
    const bool half = now_ms - p.first_seen_ms >= options_.deadline_ms / 2;
    if (!all && !half) continue;
    FrameCandidates c;
    c.frame_seq = seq;
    std::vector<Shortlist> lists;
    for (const auto& [partition, list] : p.shortlists) {
      c.merged.push_back(partition);
      p.merged.insert(partition);
      lists.push_back(list);
    }
    c.candidates = MergeShortlists(lists, options_.query);
    p.candidates_out = true;
    out.push_back(std::move(c));
  }
  return out;
}

FrameAnswer VoteCollector::Answer(uint64_t seq, Pending&& p, double now_ms) {
  FrameAnswer a;
  a.frame_seq = seq;
  a.run = run_;
  std::vector<QueryResult> parts;
  for (auto& [partition, result] : p.partials) {
    a.answered.push_back(partition);
    parts.push_back(std::move(result));
  }
  for (int i = 0; i < options_.num_partitions; ++i) {
    if (!p.partials.count(i)) a.missing.push_back(i);
  }
  a.result = MergeQueryResults(parts, options_.query);
  // Two rounds: the bag-of-words scoring was the shortlists', a round of its
  // own before the answers: the slowest shortlist's time adds to the total.
  double shortlist_ms = 0.0;
  for (const auto& [partition, list] : p.shortlists) {
    a.result.deadline_reached = a.result.deadline_reached || list.deadline_reached;
    shortlist_ms = std::max(shortlist_ms, list.retrieve_ms);
  }
  a.result.times.retrieve_ms = std::max(a.result.times.retrieve_ms, shortlist_ms);
  a.result.times.total_ms += shortlist_ms;
  a.waited_ms = std::max(0.0, now_ms - p.first_seen_ms);
  ++stats_.answered;
  ++(a.complete() ? stats_.complete : stats_.partial);
  return a;
}

std::vector<FrameAnswer> VoteCollector::Poll(double now_ms) {
  std::vector<FrameAnswer> ready = std::move(flushed_);
  flushed_.clear();
  std::vector<uint64_t> done;
  const size_t excess = pending_.size() > static_cast<size_t>(options_.max_pending)
                            ? pending_.size() - static_cast<size_t>(options_.max_pending)
                            : 0;
  size_t evicted = 0;
  for (auto& [seq, p] : pending_) {
    // Two rounds: every partition merged has answered (the others cannot).
    const bool complete = two_rounds_
                              ? p.candidates_out && p.partials.size() == p.merged.size()
                              : static_cast<int>(p.partials.size()) == options_.num_partitions;
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
    answered_.insert(seq);
  }
  // The numbers answered are remembered as far back as a frame can be late
  // (max_pending below the newest); below that, a number means a new run.
  const uint64_t window = static_cast<uint64_t>(options_.max_pending);
  if (any_answered_ && newest_answered_ > window)
    answered_.erase(answered_.begin(), answered_.lower_bound(newest_answered_ - window));
  if (options_.sequence) {
    if (!sequence_) {
      PLACEDB_THROW_INVALID("`sequence` is on but the vote has no keyframe table (UseSequence)");
    }
    for (FrameAnswer& a : ready) {
      if (a.run != sequence_run_) {
        sequence_->Reset();
        sequence_run_ = a.run;
        sequence_last_.reset();
      }
      if (sequence_last_ && a.frame_seq <= *sequence_last_) continue;  // late: by itself
      sequence_last_ = a.frame_seq;
      a.result = sequence_->Feed(std::move(a.result));
    }
  }
  return ready;
}

void VoteCollector::UseSequence(const std::vector<Keyframe>& keyframes) {
  sequence_.emplace(keyframes, options_.sequence_options);
  sequence_run_.clear();
  sequence_last_.reset();
}

void DescribeKeyframes(const PlaceDatabase& keyframes, QueryResult* result) {
  for (RankedKeyframe& r : result->ranked) {
    const std::optional<Keyframe> k = keyframes.FindKeyframe(r.keyframe_id);
    if (!k) continue;
    r.pose = k->pose;
    r.timestamp = k->timestamp;
    r.source = k->source;
  }
}

}  // namespace placedb
