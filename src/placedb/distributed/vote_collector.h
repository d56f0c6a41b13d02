// The voting node's bookkeeping, without any transport: the partial results
// of N partitions arrive per frame, in any order, some late, some never; a
// frame is answered as soon as every partition has answered, or when its
// deadline passes with what has arrived (naming the partitions that did not
// answer). Answers are merged by MergeQueryResults, the same voting function
// as the threaded query, so a complete answer equals the whole database's.
//
// Bag-of-words search (query.retrieval.method kBow, more than one
// partition) takes two rounds, because a partition's own best candidates
// are not the whole database's (query/result.h, MergeShortlists): every
// partition first sends its shortlist (OnShortlist); when all have, or at
// half the deadline with those that have, PollCandidates merges them into
// the candidates the whole database's search examines, for the transport to
// send to every partition; each then answers its share of them (OnPartial,
// an empty result when it holds none). A partition whose shortlist missed
// the merge cannot answer the frame (its keyframes were not considered):
// its answer is refused and the frame is answered without it, as missing.
// The answer's retrieve time is the slowest shortlist's, and its total the
// slowest answer's plus that (the rounds follow each other).
// BowPartitionWorker (partition_worker.h) is a partition's side.
// Not thread-safe: one caller (the voter's event loop).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "placedb/query/result.h"
#include "placedb/query/sequence.h"
#include "placedb/util/option_table.h"

namespace placedb {

class PlaceDatabase;

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
  // Answer with sequence evidence (query/sequence.h): each run's answers are
  // fed, in frame order, to a SequenceMatcher over the keyframe table given
  // to VoteCollector::UseSequence. A frame answered after a newer one (at
  // its deadline) is answered by itself. Default off.
  bool sequence = false;
  SequenceOptions sequence_options;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<VoteOptions>& Table();
  std::string Check() const;
};

// What became of one partial result handed to the collector.
enum class VoteStatus {
  kAccepted,
  kDuplicate,         // this partition already answered this frame
  kUnknownPartition,  // partition >= num_partitions
  kLate,              // the frame was answered already (complete, deadline, or evicted)
  kInconsistent,      // a keyframe twice (in it, or in another partition's result for the
                      // frame), or verified where the vote does not verify (or the reverse);
                      // a shortlist entry that another partition's shortlist gives other
                      // values: it cannot be merged, so the frame is answered without it
  kUnexpected,        // not asked for: a shortlist when the vote takes one round; in two
                      // rounds, an answer before the frame's candidates (a worker answering
                      // in one round) or from a partition whose shortlist missed the merge
};
const char* VoteStatusName(VoteStatus status);

struct FrameAnswer {
  uint64_t frame_seq = 0;
  std::string run;            // the run id of the feed that announced it ("" if none)
  QueryResult result;         // the merged answer
  std::vector<int> answered;  // partitions that answered, ascending
  std::vector<int> missing;   // partitions that did not
  bool complete() const { return missing.empty(); }
  double waited_ms = 0.0;  // from first sight of the frame to the answer
};

// The candidates of one frame in a two-round vote, for every partition.
struct FrameCandidates {
  uint64_t frame_seq = 0;
  std::vector<ShortlistEntry> candidates;  // MergeShortlists of the shortlists below
  std::vector<int> merged;                 // partitions whose shortlists were merged, ascending
};

// What the collector has done since it started: the voter reports it.
struct VoteStats {
  uint64_t answered = 0;  // frames answered (each once)
  uint64_t complete = 0;  // of them, with every partition
  uint64_t partial = 0;   // of them, without some partition
  uint64_t runs = 0;      // feed runs followed: new run ids, or numbers that started over
};

class VoteCollector {
 public:
  explicit VoteCollector(const VoteOptions& options);

  // The frame exists, announced by the feed run `run` (an id the feed makes
  // up, "" when it has none): its deadline starts now if it has not started.
  // Returns kAccepted, or kLate for a frame already answered (ignored).
  //
  // A new run resets the collector: another run id, or a number below the
  // newest announced (one feed announces in order over one connection, so
  // its numbers going back mean it started over: a bag played again). The
  // previous run's frames still pending are answered at once (next Poll),
  // with what they have, under their run's id; the new run's frames are
  // never refused as late because of the old run's numbers.
  VoteStatus OnFrame(uint64_t frame_seq, double now_ms, const std::string& run = "");
  // A partial result of `partition` for the frame (in two rounds: its
  // answer over its share of the frame's candidates).
  VoteStatus OnPartial(uint64_t frame_seq, int partition, const QueryResult& partial,
                       double now_ms);
  // Two rounds: the shortlist of `partition` for the frame (kUnexpected when
  // the vote takes one round; kLate once the frame's candidates are out).
  VoteStatus OnShortlist(uint64_t frame_seq, int partition, const Shortlist& shortlist,
                         double now_ms);
  // Two rounds: the frames whose candidates are ready at `now_ms` (every
  // partition's shortlist in, or half the deadline gone with at least one),
  // in frame order, each once. A frame without any shortlist by its
  // deadline is answered by Poll, every partition missing.
  std::vector<FrameCandidates> PollCandidates(double now_ms);
  // The vote takes two rounds (bag of words over more than one partition).
  bool two_rounds() const { return two_rounds_; }
  // The frames that are ready at `now_ms` (complete, or past their deadline,
  // or evicted), in frame order. Each frame is answered once.
  std::vector<FrameAnswer> Poll(double now_ms);
  // With options().sequence: the keyframe table the paths run through
  // (PlaceDatabase::keyframes()); required before the first Poll.
  void UseSequence(const std::vector<Keyframe>& keyframes);

  size_t pending() const { return pending_.size(); }
  const VoteOptions& options() const { return options_; }
  const VoteStats& stats() const { return stats_; }
  // The run frames are answered under: the last announced run id.
  const std::string& run() const { return run_; }

 private:
  struct Pending {
    explicit Pending(double first_seen) : first_seen_ms(first_seen) {}
    double first_seen_ms = 0.0;
    bool announced = false;               // by OnFrame (else seen only through partial results)
    std::map<int, QueryResult> partials;  // by partition
    // Two rounds: the shortlists so far, by partition; once the candidates
    // are out, the partitions merged (the answers expected).
    std::map<int, Shortlist> shortlists;
    bool candidates_out = false;
    std::set<int> merged;
  };
  FrameAnswer Answer(uint64_t seq, Pending&& p, double now_ms);
  // Answers every pending frame now (into flushed_) and forgets the numbers
  // answered: the feed started over.
  // (With keep_unannounced, frames seen only through partial results stay
  // pending: they may be the new run's.)
  void StartOver(double now_ms, bool keep_unannounced);
  // A frame answered already in this run (its number among the last
  // max_pending below the newest answered). A number far below the newest
  // answered (by more than max_pending) means the source started over: the
  // collector does too. A frame first seen after a newer one was answered
  // (frames out of order) is not stale: it is answered by its deadline.
  bool Stale(uint64_t seq, double now_ms);

  VoteOptions options_;
  bool two_rounds_ = false;
  std::map<uint64_t, Pending> pending_;
  std::set<uint64_t> answered_;       // numbers answered in this run (the last max_pending)
  std::vector<FrameAnswer> flushed_;  // answered by StartOver, returned by the next Poll
  bool any_answered_ = false;
  uint64_t newest_answered_ = 0;
  bool any_announced_ = false;
  uint64_t newest_announced_ = 0;
  std::string run_;
  VoteStats stats_;
  std::optional<SequenceMatcher> sequence_;
  std::string sequence_run_;
  std::optional<uint64_t> sequence_last_;  // the newest frame fed in sequence_run_
};

// Fills each ranked keyframe's pose, timestamp and source from the database
// (its keyframe table is enough), as a single-process query does: the
// workers' partial results carry only ids and scores.
void DescribeKeyframes(const PlaceDatabase& keyframes, QueryResult* result);

}  // namespace placedb
