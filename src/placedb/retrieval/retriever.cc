#include "placedb/retrieval/retriever.h"

#include <algorithm>

#include "placedb/match/ratio_matcher.h"
#include "placedb/retrieval/growing_bow_index.h"
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
      : index_(index), options_(options), match_(match), method_(method) {}
  RetrievalMethod method() const override { return method_; }

  std::vector<Candidate> Retrieve(const Database& db, const FeatureSet& query,
                                  const std::vector<uint32_t>* among, const uint8_t* excluded,
                                  const Deadline& deadline, bool* stopped) const override {
    return SelectGuidedCandidates(
        ScoreBowCandidates(index_, db, query, options_, match_, among, excluded, deadline, stopped),
        options_);
  }

 private:
  const GrowingBowIndex& index_;
  RetrievalOptions options_;
  MatchOptions match_;
  RetrievalMethod method_;
};

}  // namespace

std::vector<BowCandidate> ScoreBowCandidates(
    const GrowingBowIndex& index, const Database& db, const FeatureSet& query,
    const RetrievalOptions& options, const MatchOptions& match, const std::vector<uint32_t>* among,
    const uint8_t* excluded, const Deadline& deadline, bool* stopped, bool count_always) {
  if (stopped != nullptr) *stopped = false;
  if (index.size() != db.size()) {
    PLACEDB_THROW_INVALID("the bag-of-words index has ", index.size(),
                          " keyframes but the database ", db.size());
  }
  std::vector<int8_t> laplacian;
  const DescriptorBlock block = MakeDescriptorBlock(query, &laplacian);
  const bool guided = options.guided_candidates > 0;
  std::vector<uint32_t> nodes;
  const BowVector words = index.Transform(block, guided ? &nodes : nullptr);
  bool late = false;
  std::vector<BowCandidate> out;
  for (const BowIndex::Scored& s : index.Query(words, static_cast<size_t>(options.bow_candidates),
                                               among, deadline, &late, excluded))
    out.push_back({s.index, s.score, -1});
  if (stopped != nullptr) *stopped = late;
  // Out of time, the bag-of-words order stands; with no cut to make, it
  // stands too, unless the counts are asked for.
  if (!guided || late) return out;
  if (out.size() <= static_cast<size_t>(options.guided_candidates) && !count_always) return out;
  const GuidedMatcher guided_matcher(block, nodes.data(), nodes.size(), match);
  // Counted while the mean count so far still fits before the deadline (the
  // first always).
  Timer counting;
  std::vector<uint8_t> rows;  // a candidate's rows, when the database reads them
  for (size_t i = 0; i < out.size(); ++i) {
    if (i > 0 && !deadline.Fits(counting.ElapsedMs() / static_cast<double>(i))) {
      if (stopped != nullptr) *stopped = true;
      break;
    }
    const std::vector<uint32_t> kf = index.DirectNodes(out[i].index);
    out[i].guided = guided_matcher.Count(db.Descriptors(out[i].index, &rows), kf.data(), kf.size());
  }
  return out;
}

std::vector<Candidate> SelectGuidedCandidates(const std::vector<BowCandidate>& scored,
                                              const RetrievalOptions& options) {
  const size_t guided = static_cast<size_t>(options.guided_candidates);
  std::vector<Candidate> out;
  out.reserve(scored.size());
  // Not ranked, or no count at all (out of time while scoring): the
  // bag-of-words order stands, every candidate kept.
  if (guided == 0 || scored.size() <= guided || scored.front().guided < 0) {
    for (const BowCandidate& c : scored) out.push_back({c.index, c.score});
    return out;
  }
  // Most guided matches first, then the bag-of-words order (stable); the
  // uncounted (-1) after the counted, in their order.
  std::vector<BowCandidate> ranked = scored;
  std::stable_sort(ranked.begin(), ranked.end(), [](const BowCandidate& a, const BowCandidate& b) {
    return a.guided > b.guided;
  });
  ranked.resize(guided);
  for (const BowCandidate& r : ranked)
    out.push_back({r.index, static_cast<double>(std::max(0, r.guided))});
  return out;
}

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
