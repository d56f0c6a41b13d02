// The paper's matching, as a baseline to measure against: for every keyframe,
// OpenCV's BFMatcher knnMatch (k = 2) of the query's descriptors against the
// keyframe's, Lowe's ratio test, keyframes ranked by good matches.
#pragma once

#include <vector>

#include "placedb/feature/types.h"
#include "placedb/index/database.h"
#include "placedb/index/query.h"

namespace placedb {

// Same ranking rules as QueryFeatures (ratio, distance limit, min_matches,
// top_k, ties by id), computed with cv::BFMatcher on the database's stored
// descriptors. (For SURF it does not use the Laplacian sign.)
std::vector<ScoredKeyframe> BfMatcherQuery(const Database& db, const FeatureSet& query,
                                           const QueryOptions& options);

}  // namespace placedb
