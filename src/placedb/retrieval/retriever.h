// The retrieve stage: which keyframes a query examines, in which order.
//   exhaustive  every keyframe (the paper's method), in index order;
//   bow         the best keyframes by bag-of-words score (bow_index.h), best first;
//   cluster     the keyframes of the prior's spatial-locality cluster and its
//               neighbours (clusters.h; the paper's future work), falling back
//               to a global search when the local answer is weak; the two
//               stages are run by QueryDatabase (query.h), each retrieving
//               through bow or exhaustive search.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "placedb/feature/types.h"
#include "placedb/storage/database.h"
#include "placedb/match/ratio_matcher.h"
#include "placedb/util/timer.h"
#include "placedb/retrieval/options.h"

namespace placedb {

class GrowingBowIndex;

// A keyframe to examine: its index in the database and the retriever's prior
// score (higher first; 0 for exhaustive search).
struct Candidate {
  uint32_t index = 0;
  double prior = 0.0;
};

class Retriever {
 public:
  virtual ~Retriever() = default;
  virtual RetrievalMethod method() const = 0;

  // The keyframes of `db` to examine for `query`, best prior first. With
  // `among` (sorted, unique indices < db.size()), only those may be returned.
  // Once `deadline` has passed a retriever may stop early with the
  // candidates found so far and set *stopped. Keyframes marked in
  // `excluded` (nullptr: none; else one byte per keyframe of `db`, 1 = left
  // out: removed online) are never returned.
  virtual std::vector<Candidate> Retrieve(const Database& db, const FeatureSet& query,
                                          const std::vector<uint32_t>* among,
                                          const uint8_t* excluded, const Deadline& deadline,
                                          bool* stopped) const = 0;

  // The retriever for `options` over `db`. bow needs `bow`, the database's
  // index (InvalidArgument naming the fix when it is nullptr). cluster
  // retrieves through bow when `bow` is given, else exhaustively. `match`:
  // the rules guided matching counts by.
  static std::unique_ptr<Retriever> Create(const RetrievalOptions& options, const Database& db,
                                           const GrowingBowIndex* bow = nullptr,
                                           const MatchOptions& match = MatchOptions());
};

}  // namespace placedb
