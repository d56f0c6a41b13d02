#include "placedb/index/retrieval.h"

#include "placedb/index/growing_bow_index.h"
#include "placedb/match/ratio_matcher.h"
#include "placedb/util/check.h"
#include "placedb/util/options.h"

namespace placedb {

const char* RetrievalMethodName(RetrievalMethod method) {
  switch (method) {
    case RetrievalMethod::kExhaustive:
      return "exhaustive";
    case RetrievalMethod::kBow:
      return "bow";
    case RetrievalMethod::kCluster:
      return "cluster";
  }
  return "unknown";
}

RetrievalMethod ParseRetrievalMethod(const std::string& name) {
  if (name == "exhaustive") return RetrievalMethod::kExhaustive;
  if (name == "bow") return RetrievalMethod::kBow;
  if (name == "cluster") return RetrievalMethod::kCluster;
  PLACEDB_THROW_INVALID("unknown search method '", name, "' (expected exhaustive, bow or cluster)");
}

std::string RetrievalOptions::Check() const {
  if (method != RetrievalMethod::kExhaustive && method != RetrievalMethod::kBow &&
      method != RetrievalMethod::kCluster) {
    return "method is unknown";
  }
  return FirstReason({CheckRange("bow_candidates", bow_candidates, 1, 100000),
                      CheckRange("cluster_hops", cluster_hops, 0, 64),
                      CheckRange("cluster_fallback_score", cluster_fallback_score, 0.0, 100000.0)});
}

namespace {

class ExhaustiveRetriever : public Retriever {
 public:
  RetrievalMethod method() const override { return RetrievalMethod::kExhaustive; }

  std::vector<Candidate> Retrieve(const Database& db, const FeatureSet& /*query*/,
                                  const std::vector<uint32_t>* among) const override {
    std::vector<Candidate> out;
    if (among != nullptr) {
      out.reserve(among->size());
      for (const uint32_t i : *among) out.push_back({i, 0.0});
    } else {
      out.reserve(db.size());
      for (size_t i = 0; i < db.size(); ++i) out.push_back({static_cast<uint32_t>(i), 0.0});
    }
    return out;
  }
};

// The best keyframes by bag-of-words score, through the inverted file.
class BowRetriever : public Retriever {
 public:
  BowRetriever(const GrowingBowIndex& index, int candidates, RetrievalMethod method)
      : index_(index), candidates_(static_cast<size_t>(candidates)), method_(method) {}
  RetrievalMethod method() const override { return method_; }

  std::vector<Candidate> Retrieve(const Database& db, const FeatureSet& query,
                                  const std::vector<uint32_t>* among) const override {
    PLACEDB_CHECK(index_.size() == db.size(), "the bag-of-words index has ", index_.size(),
                  " keyframes but the database ", db.size());
    std::vector<int8_t> laplacian;
    const BowVector words = index_.Transform(MakeDescriptorBlock(query, &laplacian));
    std::vector<Candidate> out;
    for (const BowIndex::Scored& s : index_.Query(words, candidates_, among))
      out.push_back({s.index, s.score});
    return out;
  }

 private:
  const GrowingBowIndex& index_;
  size_t candidates_;
  RetrievalMethod method_;
};

}  // namespace

std::unique_ptr<Retriever> Retriever::Create(const RetrievalOptions& options,
                                             const Database& /*db*/, const GrowingBowIndex* bow) {
  PLACEDB_CHECK_OPTIONS(options);
  switch (options.method) {
    case RetrievalMethod::kExhaustive:
      return std::make_unique<ExhaustiveRetriever>();
    case RetrievalMethod::kBow:
      if (bow == nullptr) {
        PLACEDB_THROW_INVALID(
            "bow search needs a bag-of-words index: rebuild the database with "
            "`placedb build ... --index bow`");
      }
      return std::make_unique<BowRetriever>(*bow, options.bow_candidates, RetrievalMethod::kBow);
    case RetrievalMethod::kCluster:
      if (bow == nullptr) return std::make_unique<ExhaustiveRetriever>();
      return std::make_unique<BowRetriever>(*bow, options.bow_candidates,
                                            RetrievalMethod::kCluster);
  }
  PLACEDB_THROW_INVALID("unknown retrieval method");
}

}  // namespace placedb
