// The voting step: partial answers of disjoint partitions merged into the
// whole database's answer.
#include <algorithm>
#include <unordered_map>
#include <unordered_set>

#include "placedb/query/order.h"
#include "placedb/query/result.h"
#include "placedb/retrieval/retriever.h"
#include "placedb/util/check.h"

namespace placedb {

using namespace query_order;  // NOLINT: the rules this file applies

QueryResult MergeQueryResults(const std::vector<QueryResult>& parts, const QueryOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  QueryResult merged;
  std::vector<RankedKeyframe> all;
  std::unordered_set<int32_t> seen;
  for (const QueryResult& p : parts) {
    merged.num_query_features = std::max(merged.num_query_features, p.num_query_features);
    merged.num_keyframes += p.num_keyframes;
    merged.num_examined += p.num_examined;
    merged.num_verified += p.num_verified;
    merged.times.extract_ms = std::max(merged.times.extract_ms, p.times.extract_ms);
    merged.times.retrieve_ms = std::max(merged.times.retrieve_ms, p.times.retrieve_ms);
    merged.times.match_ms = std::max(merged.times.match_ms, p.times.match_ms);
    merged.times.verify_ms = std::max(merged.times.verify_ms, p.times.verify_ms);
    merged.times.total_ms = std::max(merged.times.total_ms, p.times.total_ms);
    merged.deadline_reached = merged.deadline_reached || p.deadline_reached;
    for (const RankedKeyframe& r : p.ranked) {
      if (!seen.insert(r.keyframe_id).second) {
        PLACEDB_THROW_INVALID("keyframe ", r.keyframe_id,
                              " is in two partial results (partitions must be disjoint)");
      }
      if (r.verified() != options.verify.enabled) {
        PLACEDB_THROW_INVALID("keyframe ", r.keyframe_id, " is ",
                              r.verified() ? "verified" : "not verified", " but the merge options ",
                              options.verify.enabled ? "" : "do not ", "verify");
      }
      all.push_back(r);
    }
  }
  // The whole database's match-stage survivors are the best of the parts'
  // (each part kept its own best, which include all of the global best).
  const size_t keep = KeptAfterMatching(options);
  // What the match stage kept: by matches plus the whole-image bonus.
  auto more_matches = [&](const RankedKeyframe& a, const RankedKeyframe& b) {
    return MoreEvidence(a.keyframe_id, MatchKey(a, options), b.keyframe_id, MatchKey(b, options));
  };
  std::sort(all.begin(), all.end(), more_matches);
  if (all.size() > keep) all.resize(keep);
  std::sort(all.begin(), all.end(), RanksFirst);
  if (all.size() > static_cast<size_t>(options.top_k)) all.resize(options.top_k);
  merged.ranked = std::move(all);
  Decide(&merged, options);
  merged.coverage = CoverageOf(merged);
  if (!parts.empty()) {
    merged.search = parts.front().search;
    merged.cluster = parts.front().cluster;
  }
  return merged;
}

namespace {

// The union of the parts' lists `list`: one entry per keyframe (a keyframe
// offered by two parts must come with the same values), best score first,
// ties: the lower index.
std::vector<ShortlistEntry> UnionOf(const std::vector<Shortlist>& parts,
                                    std::vector<ShortlistEntry> Shortlist::*list,
                                    const char* what) {
  std::vector<ShortlistEntry> all;
  std::unordered_map<uint32_t, ShortlistEntry> seen;
  for (const Shortlist& p : parts) {
    for (const ShortlistEntry& e : p.*list) {
      const auto [it, inserted] = seen.emplace(e.index, e);
      if (inserted) {
        all.push_back(e);
      } else if (!(it->second == e)) {
        PLACEDB_THROW_INVALID("keyframe index ", e.index, " is in two ", what,
                              " shortlists with different values (the parts must query one "
                              "database with the same options)");
      }
    }
  }
  std::sort(all.begin(), all.end(), [](const ShortlistEntry& a, const ShortlistEntry& b) {
    return a.score != b.score ? a.score > b.score : a.index < b.index;
  });
  return all;
}

}  // namespace

std::vector<ShortlistEntry> MergeShortlists(const std::vector<Shortlist>& parts,
                                            const QueryOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  std::vector<ShortlistEntry> bow = UnionOf(parts, &Shortlist::bow, "bag-of-words");
  if (bow.size() > static_cast<size_t>(options.retrieval.bow_candidates))
    bow.resize(static_cast<size_t>(options.retrieval.bow_candidates));
  // The guided cut, as the whole database's search makes it.
  std::vector<BowCandidate> scored;
  scored.reserve(bow.size());
  std::unordered_map<uint32_t, const ShortlistEntry*> by_index;
  for (const ShortlistEntry& e : bow) {
    scored.push_back({e.index, e.score, e.guided});
    by_index.emplace(e.index, &e);
  }
  std::vector<ShortlistEntry> out;
  std::unordered_set<uint32_t> have;
  for (const Candidate& c : SelectGuidedCandidates(scored, options.retrieval)) {
    out.push_back(*by_index.at(c.index));
    have.insert(c.index);
  }
  std::vector<ShortlistEntry> whole = UnionOf(parts, &Shortlist::whole_image, "whole-image");
  if (whole.size() > static_cast<size_t>(options.whole_image_candidates))
    whole.resize(static_cast<size_t>(options.whole_image_candidates));
  for (const ShortlistEntry& e : whole) {
    if (have.insert(e.index).second) out.push_back(e);
  }
  return out;
}

}  // namespace placedb
