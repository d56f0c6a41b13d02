// The options of the retrieve stage: the method, bag-of-words candidates,
// clusters, the vocabulary's training and the direct index (part of the
// public face, placedb/placedb.h).
#pragma once

#include <cstdint>
#include <string>

#include "placedb/util/option_table.h"

namespace placedb {

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

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<RetrievalOptions>& Table();
  std::string Check() const;
};

struct ClusterOptions {
  // Radius of a cluster around its seed, in the poses' unit (metres). Range
  // (0, 1e6]. Default 1.0.
  double radius_m = 1.0;
  // Keyframes per cluster when there are no poses. Range [1, 1000000].
  // Default 20.
  int time_keyframes = 20;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<ClusterOptions>& Table();
  std::string Check() const;
};

struct VocabularyOptions {
  // k, the children of each node. Range [2, 64]. Default 10.
  int branching = 10;
  // Levels below the root (words are at most this deep). Range [1, 8], and
  // branching^depth <= 2^24 words. Default 5.
  int depth = 5;
  // Clustering (k-majority / k-means) iterations per node; a node stops
  // earlier when no row changes cluster. Range [1, 100]. Default 10.
  int iterations = 10;
  // Training uses a random sample of at most this many descriptor rows (all
  // of them when there are fewer); the IDF weights count every row. Range
  // [1000, 100000000]. Default 1000000.
  int max_training_descriptors = 1000000;
  // Everything random in training derives from it (std::mt19937_64). Any
  // value. Default 1.
  uint64_t seed = 1;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<VocabularyOptions>& Table();
  std::string Check() const;
};

struct BowIndexOptions {
  // Level of the direct index's nodes (0 = the root, which puts every row
  // under one node). Range [0, 8], and at most the vocabulary's depth (Build
  // checks). Default 2.
  int direct_level = 2;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<BowIndexOptions>& Table();
  std::string Check() const;
};

}  // namespace placedb
