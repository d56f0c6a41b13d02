#include "placedb/retrieval/retriever.h"

#include <algorithm>

#include "placedb/retrieval/growing_bow_index.h"
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

namespace {

class ExhaustiveRetriever : public Retriever {
 public:
  RetrievalMethod method() const override { return RetrievalMethod::kExhaustive; }

  std::vector<Candidate> Retrieve(const Database& db, const FeatureSet& /*query*/,
                                  const std::vector<uint32_t>* among, const uint8_t* excluded,
                                  const Deadline& /*deadline*/, bool* /*stopped*/) const override {
    std::vector<Candidate> out;
    if (among != nullptr) {
      out.reserve(among->size());
      for (const uint32_t i : *among) {
        if (excluded == nullptr || !excluded[i]) out.push_back({i, 0.0});
      }
    } else {
      out.reserve(db.size());
      for (size_t i = 0; i < db.size(); ++i) {
        if (excluded == nullptr || !excluded[i]) out.push_back({static_cast<uint32_t>(i), 0.0});
      }
    }
    return out;
  }
};

// The best keyframes by bag-of-words score, through the inverted file, then
// (guided_candidates) the best of those by guided matching.
class BowRetriever : public Retriever {
 public:
  BowRetriever(const GrowingBowIndex& index, const RetrievalOptions& options,
               const MatchOptions& match, RetrievalMethod method)
      : index_(index),
        candidates_(static_cast<size_t>(options.bow_candidates)),
        guided_(static_cast<size_t>(options.guided_candidates)),
        match_(match),
        method_(method) {}
  RetrievalMethod method() const override { return method_; }

  std::vector<Candidate> Retrieve(const Database& db, const FeatureSet& query,
                                  const std::vector<uint32_t>* among, const uint8_t* excluded,
                                  const Deadline& deadline, bool* stopped) const override {
    if (index_.size() != db.size()) {
      PLACEDB_THROW_INVALID("the bag-of-words index has ", index_.size(),
                            " keyframes but the database ", db.size());
    }
    std::vector<int8_t> laplacian;
    const DescriptorBlock block = MakeDescriptorBlock(query, &laplacian);
    const bool guided = guided_ > 0;
    std::vector<uint32_t> nodes;
    const BowVector words = index_.Transform(block, guided ? &nodes : nullptr);
    bool late = false;
    std::vector<Candidate> out;
    for (const BowIndex::Scored& s : index_.Query(words, candidates_, among, deadline, &late, excluded))
      out.push_back({s.index, s.score});
    if (stopped != nullptr) *stopped = late;
    // Out of time, the bag-of-words order stands.
    if (!guided || late || out.size() <= guided_) return out;
    const GuidedMatcher guided_matcher(block, nodes.data(), nodes.size(), match_);
    struct Ranked {
      Candidate c;
      int guided;
    };
    // Counted while the mean count so far still fits before the deadline
    // (the first always); the uncounted keep their bag-of-words order after
    // the counted ones.
    std::vector<Ranked> ranked;
    ranked.reserve(out.size());
    Timer counting;
    for (const Candidate& c : out) {
      if (!ranked.empty() && !deadline.Fits(counting.ElapsedMs() / ranked.size())) {
        if (stopped != nullptr) *stopped = true;
        break;
      }
      const Span<uint32_t> kf = index_.DirectNodes(c.index);
      ranked.push_back({c, guided_matcher.Count(db.Descriptors(c.index), kf.data(), kf.size())});
    }
    const size_t counted = ranked.size();
    for (size_t i = counted; i < out.size(); ++i) ranked.push_back({out[i], -1});
    // Most guided matches first; then the bag-of-words order (stable).
    std::stable_sort(ranked.begin(), ranked.begin() + static_cast<std::ptrdiff_t>(counted),
                     [](const Ranked& a, const Ranked& b) { return a.guided > b.guided; });
    ranked.resize(guided_);
    out.clear();
    for (const Ranked& r : ranked)
      out.push_back({r.c.index, static_cast<double>(std::max(0, r.guided))});
    return out;
  }

 private:
  const GrowingBowIndex& index_;
  size_t candidates_;
  size_t guided_;
  MatchOptions match_;
  RetrievalMethod method_;
};

}  // namespace

std::unique_ptr<Retriever> Retriever::Create(const RetrievalOptions& options,
                                             const Database& /*db*/, const GrowingBowIndex* bow,
                                             const MatchOptions& match) {
  PLACEDB_CHECK_OPTIONS(options);
  switch (options.method) {
    case RetrievalMethod::kExhaustive:
      return std::make_unique<ExhaustiveRetriever>();
    case RetrievalMethod::kBow:
      if (bow == nullptr) {
        PLACEDB_THROW_INVALID(
            "bow search needs a bag-of-words index: rebuild the database with `index` set to "
            "bow");
      }
      return std::make_unique<BowRetriever>(*bow, options, match, RetrievalMethod::kBow);
    case RetrievalMethod::kCluster:
      if (bow == nullptr) return std::make_unique<ExhaustiveRetriever>();
      return std::make_unique<BowRetriever>(*bow, options, match, RetrievalMethod::kCluster);
  }
  PLACEDB_THROW_INVALID("unknown retrieval method");
}

}  // namespace placedb
