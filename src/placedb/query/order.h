// The order and the decision of a query's answer, shared by the stages
// (query.cc) and the voting merge (merge.cc), so that a merged answer ranks
// and decides exactly as the whole database's.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>

#include "placedb/query/result.h"

namespace placedb {
namespace query_order {

// Match-stage order: more matches first, then the lower id.
inline bool MoreMatches(int32_t id_a, int a, int32_t id_b, int b) {
  return a != b ? a > b : id_a < id_b;
}

// The whole-image channel's part of a score: weight x max(0, z - floor) of
// the standardised similarity z; 0 without the channel.
inline double WholeImageBonus(const std::optional<double>& z, const QueryOptions& options) {
  return z ? options.whole_image_weight * std::max(0.0, *z - options.whole_image_floor) : 0.0;
}

// The match stage's key: matches plus the whole-image bonus. A verified score
// (inliers plus the same bonus) never exceeds it.
inline double MatchKey(const RankedKeyframe& r, const QueryOptions& options) {
  return r.num_matches + WholeImageBonus(r.whole_image_z, options);
}

// A keyframe's local-feature evidence: inliers when verified, else matches.
inline double FeatureScore(const RankedKeyframe& r) {
  return r.verified() ? r.num_inliers : r.num_matches;
}

// A keyframe's whole score: its feature score plus the whole-image bonus.
inline double FusedScore(const RankedKeyframe& r, const QueryOptions& options) {
  return FeatureScore(r) + WholeImageBonus(r.whole_image_z, options);
}

// A verified keyframe's score: its inliers plus the whole-image bonus.
inline double VerifiedScore(const RankedKeyframe& r, const QueryOptions& options) {
  return r.num_inliers + WholeImageBonus(r.whole_image_z, options);
}

// Match-stage order on keys: the larger first, then the lower id.
inline bool MoreEvidence(int32_t id_a, double a, int32_t id_b, double b) {
  return a != b ? a > b : id_a < id_b;
}

// Final order: by score (verified: inliers, else matches; plus the
// whole-image bonus), then matches, then id.
inline bool RanksFirst(const RankedKeyframe& a, const RankedKeyframe& b) {
  if (a.score != b.score) return a.score > b.score;
  return MoreMatches(a.keyframe_id, a.num_matches, b.keyframe_id, b.num_matches);
}

inline void Decide(QueryResult* r, const QueryOptions& options) {
  r->matched = !r->ranked.empty() && r->ranked.front().score >= options.min_score;
}

inline double CoverageOf(const QueryResult& r) {
  return r.num_keyframes == 0
             ? 0.0
             : static_cast<double>(r.num_examined) / static_cast<double>(r.num_keyframes);
}

// How many of the match stage's best keyframes go on.
inline size_t KeptAfterMatching(const QueryOptions& options) {
  return static_cast<size_t>(options.verify.enabled ? options.verify.num_candidates
                                                    : options.top_k);
}

}  // namespace query_order
}  // namespace placedb
