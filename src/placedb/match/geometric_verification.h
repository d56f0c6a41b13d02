// The verify stage: RANSAC (OpenCV's USAC) on the matches between the query
// and one keyframe. The number of matches consistent with one epipolar
// geometry (fundamental matrix) or one plane (homography) is the verified
// score: chance matches rarely agree on a geometry, true ones do.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace placedb {

enum class GeometricModel { kFundamental, kHomography };
// "fundamental" / "homography".
const char* GeometricModelName(GeometricModel model);
// Parses those names; throws InvalidArgument.
GeometricModel ParseGeometricModel(const std::string& name);

struct VerifyOptions {
  // Verify the best candidates of the match stage and rank them by inliers.
  // Default true.
  bool enabled = true;
  // Fundamental matrix (any static scene, the robot moving) or homography
  // (planar scenes, pure rotation). Default fundamental.
  GeometricModel model = GeometricModel::kFundamental;
  // How many of the match stage's best keyframes are verified; the ranked list
  // of a verified query holds only these. Range [1, 1000]. Default 10.
  int num_candidates = 10;
  // Largest distance of an inlier from its epipolar line / its projection,
  // pixels of the query image. Range (0, 100]. Default 3.
  double max_error_px = 3.0;
  // RANSAC confidence. Range [0.5, 1). Default 0.999.
  double confidence = 0.999;
  // RANSAC iterations at most. Range [1, 100000]. Default 2000.
  int max_iterations = 2000;
  // Seed of RANSAC's sampling: the same seed, the same inliers, on any
  // thread. Range [0, 2^31). Default 0.
  int seed = 0;

  std::string Check() const;
};

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
