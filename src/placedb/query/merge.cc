// The voting step: partial answers of disjoint partitions merged into the
// whole database's answer.
#include <algorithm>
#include <unordered_set>

#include "placedb/query/order.h"
#include "placedb/query/result.h"
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

}  // namespace placedb
