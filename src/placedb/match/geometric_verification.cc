#include "placedb/match/geometric_verification.h"

#include <cmath>
#include <opencv2/calib3d.hpp>

#include "placedb/util/check.h"
#include "placedb/util/options.h"

namespace placedb {

const char* GeometricModelName(GeometricModel model) {
  return model == GeometricModel::kHomography ? "homography" : "fundamental";
}

GeometricModel ParseGeometricModel(const std::string& name) {
  if (name == "fundamental") return GeometricModel::kFundamental;
  if (name == "homography") return GeometricModel::kHomography;
  PLACEDB_THROW_INVALID("unknown geometric model '", name,
                        "' (expected fundamental or homography)");
}

int MinimumMatches(GeometricModel model) { return model == GeometricModel::kHomography ? 4 : 8; }

VerifyResult VerifyMatches(const std::vector<cv::Point2f>& query_points,
                           const std::vector<cv::Point2f>& keyframe_points,
                           const VerifyOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  if (query_points.size() != keyframe_points.size()) {
    PLACEDB_THROW_INVALID("verification needs one keyframe point per query point (",
                          query_points.size(), " query points, ", keyframe_points.size(),
                          " keyframe points)");
  }
  for (size_t i = 0; i < query_points.size(); ++i) {
    const cv::Point2f& a = query_points[i];
    const cv::Point2f& b = keyframe_points[i];
    if (!std::isfinite(a.x) || !std::isfinite(a.y) || !std::isfinite(b.x) || !std::isfinite(b.y))
      PLACEDB_THROW_INVALID("point pair ", i, " is not finite");
  }
  VerifyResult result;
  if (static_cast<int>(query_points.size()) < MinimumMatches(options.model)) return result;
  cv::UsacParams params;  // USAC defaults (uniform sampling, MSAC score, local optimisation)
  params.threshold = options.max_error_px;
  params.confidence = options.confidence;
  params.maxIterations = options.max_iterations;
  params.randomGeneratorState = options.seed;
  params.isParallel = false;  // deterministic, and the caller parallelises
  auto estimate = [&](GeometricModel model, cv::Mat* mask) {
    try {
      return model == GeometricModel::kFundamental
                 ? cv::findFundamentalMat(query_points, keyframe_points, *mask, params)
                 : cv::findHomography(query_points, keyframe_points, *mask, params);
    } catch (const cv::Exception&) {
      return cv::Mat();  // degenerate input: no model
    }
  };
  cv::Mat mask;
  result.model = estimate(options.model, &mask);
  if ((result.model.empty() || mask.empty()) && options.model == GeometricModel::kFundamental) {
    // No epipolar geometry: the views may be related by a homography (the
    // camera did not move, or only turned; a planar scene), where a
    // fundamental matrix is degenerate.
    mask.release();
    result.model = estimate(GeometricModel::kHomography, &mask);
  }
  if (result.model.empty() || mask.empty()) return VerifyResult();
  // OpenCV may return several stacked 3x3 solutions; the mask goes with the first.
  result.model = result.model.rowRange(0, 3).clone();
  result.estimated = true;
  result.inlier_mask.assign(mask.begin<uint8_t>(), mask.end<uint8_t>());
  for (uint8_t m : result.inlier_mask) result.num_inliers += m != 0;
  return result;
}

}  // namespace placedb
