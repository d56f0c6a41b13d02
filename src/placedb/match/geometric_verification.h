// The verify stage: RANSAC (OpenCV's USAC) on the matches between the query
// and one keyframe. The number of matches consistent with one epipolar
// geometry (fundamental matrix) or one plane (homography) is the verified
// score: chance matches rarely agree on a geometry, true ones do.
#pragma once

#include "placedb/match/options.h"

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace placedb {

// Fewest matches a model can be estimated from (8 for a fundamental matrix,
// 4 for a homography); with fewer, there is nothing to verify.
int MinimumMatches(GeometricModel model);

struct VerifyResult {
  int num_inliers = 0;
  bool estimated = false;            // a model was found
  std::vector<uint8_t> inlier_mask;  // one per match when estimated
  cv::Mat model;                     // 3x3 CV_64F when estimated
};

// Runs USAC on point pairs (query image, keyframe in its original image's
// coordinates). When no fundamental matrix can be estimated (the camera did
// not move or only rotated, which makes it degenerate), a homography is
// tried instead. Sizes must agree; non-finite points are invalid input
// (InvalidArgument). Fewer than MinimumMatches pairs: 0 inliers.
// Deterministic for a given seed. Thread-safe.
VerifyResult VerifyMatches(const std::vector<cv::Point2f>& query_points,
                           const std::vector<cv::Point2f>& keyframe_points,
                           const VerifyOptions& options);

}  // namespace placedb
