// The option tables of the retrieve stage: which candidates (exhaustive,
// bag of words, clusters), the vocabulary's training and the direct index
// (util/option_table.h).
#include "placedb/retrieval/options.h"
#include "placedb/util/option_table.h"

namespace placedb {

const OptionTable<RetrievalOptions>& RetrievalOptions::Table() {
  static const OptionTable<RetrievalOptions> table = [] {
    using O = RetrievalOptions;
    OptionTable<O> t("retrieval options");
    t.Choice("search", PLACEDB_MEMBER(O, method),
             {RetrievalMethod::kExhaustive, RetrievalMethod::kBow, RetrievalMethod::kCluster},
             ParseRetrievalMethod, RetrievalMethodName,
             "retrieve stage: exhaustive (every keyframe), bow (bag-of-words candidates; needs a "
             "database built with index bow) or cluster (the prior's spatial-locality clusters "
             "first, then the rest when the answer is weak)");
    t.Number("bow_candidates", PLACEDB_MEMBER(O, bow_candidates), OptionRange::Closed(1, 100000),
             "bow: keyframes scored best by bag of words");
    t.Number("guided_candidates", PLACEDB_MEMBER(O, guided_candidates),
             OptionRange::Closed(0, 100000),
             "bow: of those, the ones with the most guided matches (same vocabulary node) are "
             "matched in full; 0 = all");
    t.Number("cluster_hops", PLACEDB_MEMBER(O, cluster_hops), OptionRange::Closed(0, 64),
             "cluster: neighbour clusters searched around the prior's, in hops");
    t.Number("cluster_fallback_score", PLACEDB_MEMBER(O, cluster_fallback_score),
             OptionRange::Closed(0, 100000),
             "cluster: a local best score below this searches the rest of the database (0: "
             "`min_score`)");
    return t;
  }();
  return table;
}

std::string RetrievalOptions::Check() const { return Table().Check(*this); }

const OptionTable<ClusterOptions>& ClusterOptions::Table() {
  static const OptionTable<ClusterOptions> table = [] {
    using O = ClusterOptions;
    OptionTable<O> t("cluster options");
    t.Number("cluster_radius", PLACEDB_MEMBER(O, radius_m), OptionRange::LeftOpen(0, 1e6),
             "cluster search: radius of a spatial cluster, in the poses' unit");
    t.Number("cluster_keyframes", PLACEDB_MEMBER(O, time_keyframes),
             OptionRange::Closed(1, 1e6),
             "cluster search without poses: consecutive keyframes per cluster");
    return t;
  }();
  return table;
}

std::string ClusterOptions::Check() const { return Table().Check(*this); }

const OptionTable<VocabularyOptions>& VocabularyOptions::Table() {
  static const OptionTable<VocabularyOptions> table = [] {
    using O = VocabularyOptions;
    OptionTable<O> t("vocabulary options");
    t.Number("vocabulary_branching", PLACEDB_MEMBER(O, branching), OptionRange::Closed(2, 64),
             "bow: children per node");
    t.Number("vocabulary_depth", PLACEDB_MEMBER(O, depth), OptionRange::Closed(1, 8),
             "bow: levels of the vocabulary tree (branching^depth at most 2^24 words)");
    t.Number("vocabulary_iterations", PLACEDB_MEMBER(O, iterations), OptionRange::Closed(1, 100),
             "bow: clustering iterations per node");
    t.Number("vocabulary_sample", PLACEDB_MEMBER(O, max_training_descriptors),
             OptionRange::Closed(1000, 1e8), "bow: descriptors sampled for training");
    t.Number("vocabulary_seed", PLACEDB_MEMBER(O, seed), OptionRange::Any(),
             "bow: training seed");
    t.Rule([](const O& o) -> std::string {
      double words = 1.0;
      for (int d = 0; d < o.depth; ++d) words *= o.branching;
      if (words <= double{1 << 24}) return "";
      return "`vocabulary_branching`^`vocabulary_depth` must be at most 2^24 words (got " +
             std::to_string(o.branching) + "^" + std::to_string(o.depth) + ")";
    });
    return t;
  }();
  return table;
}

std::string VocabularyOptions::Check() const { return Table().Check(*this); }

const OptionTable<BowIndexOptions>& BowIndexOptions::Table() {
  static const OptionTable<BowIndexOptions> table = [] {
    using O = BowIndexOptions;
    OptionTable<O> t("index options");
    t.Number("direct_level", PLACEDB_MEMBER(O, direct_level), OptionRange::Closed(0, 8),
             "bow: vocabulary level of the direct index (at most `vocabulary_depth`)");
    return t;
  }();
  return table;
}

std::string BowIndexOptions::Check() const { return Table().Check(*this); }

}  // namespace placedb
