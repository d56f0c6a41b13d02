// The paper's matching, as a baseline to measure against: for every keyframe,
// OpenCV's BFMatcher knnMatch (k = 2) of the query's descriptors against the
// keyframe's, Lowe's ratio test, keyframes ranked by matches. The same match
// rules as placedb's match stage (distance limit, one-to-one, cross-check),
// so both rank the same keyframes and only the speed differs.
#pragma once

#include <vector>

#include "placedb/feature/types.h"
#include "placedb/storage/database.h"
#include "placedb/query/query.h"
#include "placedb/query/ranking.h"

namespace placedb {

// Keyframes ranked by matches (ties: lower id), the top options.top_k, with
// at least options.min_matches each; computed with cv::BFMatcher on the
// database's stored descriptors. (It knows no Laplacian sign: compare SURF
// with match.use_laplacian_sign off.)
std::vector<ScoredKeyframe> BfMatcherQuery(const Database& db, const FeatureSet& query,
                                           const QueryOptions& options);

}  // namespace placedb
