// One partition's side of a bag-of-words search split over partitions in two
// rounds (query/result.h, MergeShortlists; the voter's side is
// VoteCollector), without any transport: the ROS worker node's logic.
//   round 1: MakeShortlist(frame, features): the partition's shortlist; the
//            features are kept for round 2;
//   round 2: Answer(frame, candidates): the answer over the partition's
//            share of the merged candidates (exhaustive search among them,
//            options.ForPartition()), an empty one when it holds none of
//            them; the frame's features are forgotten.
// The session must be opened on the whole database (BowShortlist needs it;
// mapped, its memory follows what the partition reads) and outlive the
// worker, which refers to it. Not thread-safe: one caller (the worker's
// event loop).
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

#include "placedb/query/result.h"
#include "placedb/session/place_database.h"
#include "placedb/storage/keyframe_subset.h"

namespace placedb {

class BowPartitionWorker {
 public:
  // `partition`: kPartition, the part this worker answers for. `options`:
  // the query options (bag-of-words search), as the voter's. At most
  // `max_pending` frames' features are kept between the rounds (the oldest
  // frame number forgotten first). InvalidArgument for another subset kind,
  // options that are not bag-of-words search, a session opened on a subset,
  // or max_pending 0.
  BowPartitionWorker(const PlaceDatabase& db, const KeyframeSubset& partition,
                     const QueryOptions& options, size_t max_pending = 64);

  // Round 1 for frame `frame_seq` (a frame number seen again replaces the
  // features kept for it: a feed that started over).
  Shortlist MakeShortlist(uint64_t frame_seq, FeatureSet features);
  // Round 2. InvalidArgument when the frame's features are not kept (never
  // shortlisted here, answered already, or forgotten), or a candidate is not
  // this database's keyframe (its index and id disagree with the file).
  QueryResult Answer(uint64_t frame_seq, const std::vector<ShortlistEntry>& candidates);

  size_t pending() const { return features_.size(); }
  const std::vector<int32_t>& keyframe_ids() const { return mine_; }

 private:
  const PlaceDatabase& db_;
  KeyframeSubset partition_;
  QueryOptions options_;
  QueryOptions share_;  // round 2: exhaustive among the share, ForPartition
  size_t max_pending_;
  std::vector<int32_t> ids_;   // every keyframe's id, by index
  std::vector<int32_t> mine_;  // this partition's
  std::map<uint64_t, FeatureSet> features_;
};

}  // namespace placedb
