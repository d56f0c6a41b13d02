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

namespace placedb {

class GrowingBowIndex;

enum class RetrievalMethod { kExhaustive, kBow, kCluster };
// "exhaustive", "bow", "cluster".
const char* RetrievalMethodName(RetrievalMethod method);
// Parses a name; throws InvalidArgument naming the known ones.
RetrievalMethod ParseRetrievalMethod(const std::string& name);

struct RetrievalOptions {
  // How candidates are chosen. Default exhaustive.
  RetrievalMethod method = RetrievalMethod::kExhaustive;
  // bow (and cluster over a database with a BoW index): keyframes passed on
  // to matching, best bag-of-words score first. Range [1, 100000]. Default 40.
  int bow_candidates = 40;
  // bow and cluster: of those, the ones with the most guided matches (query
  // and keyframe features under the same vocabulary node at the index's
  // direct level, CountGuidedMatches) go on to the full match stage, at a
  // small share of its cost; 0 = all of them, in bag-of-words order. Range
  // [0, 100000]. Default 5: on data/rtabmap_loop and on the scale
  // benchmark's augmented sets, recall@1 with 5 equals that with 10 (and
  // that of exhaustive search) for half the match and verify work (README,
  // "Retrieval at scale", the "guided 10" rows).
  int guided_candidates = 5;
  // cluster: the prior's cluster and its neighbours up to this many hops of
  // the neighbour graph are searched first. Range [0, 64]. Default 1.
  int cluster_hops = 1;
  // cluster: a local answer whose score is below this falls back to a global
  // search (a local "no match" always does). Range [0, 100000]; 0 = the
  // query's min_score. Default 0.
  double cluster_fallback_score = 0.0;

  std::string Check() const;
};

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
