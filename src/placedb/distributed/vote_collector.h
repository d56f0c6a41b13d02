// The voting node's bookkeeping, without any transport: the partial results
// of N partitions arrive per frame, in any order, some late, some never; a
// frame is answered as soon as every partition has answered, or when its
// deadline passes with what has arrived (naming the partitions that did not
// answer). Answers are merged by MergeQueryResults, the same voting function
// as the threaded query, so a complete answer equals the whole database's.
// Not thread-safe: one caller (the voter's event loop).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "placedb/query/result.h"
#include "placedb/util/option_table.h"

namespace placedb {

struct VoteOptions {
  // Partitions the database is split into. Range [1, 4096].
  int num_partitions = 1;
  // A frame is answered at the latest this long after it was first seen
  // (its announcement or its first partial result), milliseconds. Range
  // (0, 600000]. Default 500.
  double deadline_ms = 500.0;
  // Frames waiting at once at most; beyond it the oldest is answered now.
  // Range [1, 100000]. Default 256.
  int max_pending = 256;
  // How answers rank and decide (top_k, verification, min_score): the
  // options the workers ran with, before ForPartition.
  QueryOptions query;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<VoteOptions>& Table();
  std::string Check() const;
};

// What became of one partial result handed to the collector.
enum class VoteStatus {
  kAccepted,
  kDuplicate,         // this partition already answered this frame
  kUnknownPartition,  // partition >= num_partitions
  kLate,              // the frame was answered already (deadline, or evicted)
};
const char* VoteStatusName(VoteStatus status);

struct FrameAnswer {
  uint64_t frame_seq = 0;
  QueryResult result;         // the merged answer
  std::vector<int> answered;  // partitions that answered, ascending
  std::vector<int> missing;   // partitions that did not
  bool complete() const { return missing.empty(); }
  double waited_ms = 0.0;  // from first sight of the frame to the answer
};

class VoteCollector {
 public:
  explicit VoteCollector(const VoteOptions& options);

  // The frame exists (announced by the feed): its deadline starts now if it
  // has not started. A frame already answered (or stale) is ignored.
  void OnFrame(uint64_t frame_seq, double now_ms);
  // A partial result of `partition` for the frame.
  VoteStatus OnPartial(uint64_t frame_seq, int partition, const QueryResult& partial,
                       double now_ms);
  // The frames that are ready at `now_ms` (complete, or past their deadline,
  // or evicted), in frame order. Each frame is answered once.
  std::vector<FrameAnswer> Poll(double now_ms);

  size_t pending() const { return pending_.size(); }
  const VoteOptions& options() const { return options_; }

 private:
  struct Pending {
    double first_seen_ms = 0.0;
    std::map<int, QueryResult> partials;  // by partition
  };
  FrameAnswer Answer(uint64_t seq, Pending&& p, double now_ms) const;
  // A frame not pending and not newer than the newest answered one: answered
  // already, or first seen after a newer frame was answered (stale). A frame
  // far older than that (by more than max_pending) means the feed started
  // over: the collector does too.
  bool Stale(uint64_t seq);

  VoteOptions options_;
  std::map<uint64_t, Pending> pending_;
  bool any_answered_ = false;
  uint64_t newest_answered_ = 0;
};

}  // namespace placedb
