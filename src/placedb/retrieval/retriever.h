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
#include "placedb/match/ratio_matcher.h"
#include "placedb/retrieval/options.h"
#include "placedb/storage/database.h"
#include "placedb/util/timer.h"

namespace placedb {

class GrowingBowIndex;

// A keyframe to examine: its index in the database and the retriever's prior
// score (higher first; 0 for exhaustive search).
struct Candidate {
  uint32_t index = 0;
  double prior = 0.0;
};

// A bag-of-words candidate before the guided cut (retriever.cc's bow
// search in two steps, so that a search split over partitions can merge the
// first step's lists before it takes the second: query/query.h,
// ShortlistDatabase).
struct BowCandidate {
  uint32_t index = 0;  // keyframe index in the database
  double score = 0.0;  // bag-of-words score (BowIndex::Query)
  int guided = -1;     // guided matches; -1: not counted (no guided ranking, or out of time)
};

// Step 1: the best options.bow_candidates keyframes of `among` by
// bag-of-words score (best first, ties: the lower index), each with its
// guided match count when options.guided_candidates > 0 (counted while the
// deadline allows, the first always; the uncounted keep -1), unless the list
// is no longer than guided_candidates and not `count_always` (no cut follows:
// the bow search skips the counts; a partition's shortlist needs them).
// *stopped is set when the deadline cut the scoring or the counting.
std::vector<BowCandidate> ScoreBowCandidates(
    const GrowingBowIndex& index, const Database& db, const FeatureSet& query,
    const RetrievalOptions& options, const MatchOptions& match, const std::vector<uint32_t>* among,
    const uint8_t* excluded, const Deadline& deadline, bool* stopped, bool count_always = false);

// Step 2, on step 1's list (best bag-of-words score first): when guided
// ranking is on and the list is longer than guided_candidates, the
// guided_candidates counted ones with the most guided matches (ties: the
// list's order; the uncounted after the counted), their prior the count;
// else (or when none was counted: out of time) the whole list in its order,
// the prior the score.
std::vector<Candidate> SelectGuidedCandidates(const std::vector<BowCandidate>& scored,
                                              const RetrievalOptions& options);

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
