#include "placedb/image/feature_rich_crop.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "placedb/util/check.h"
#include "placedb/util/options.h"

namespace placedb {

int CountFastKeypoints(const cv::Mat& image, int threshold, bool nonmax) {
  if (image.empty()) return 0;
  std::vector<cv::KeyPoint> keypoints;
  cv::FAST(ToGray(image), keypoints, threshold, nonmax);
  return static_cast<int>(keypoints.size());
}

namespace {

// Value below which `1 - percentile/100` of the samples lie... i.e. the
// percentile of the plane's values, by nth_element on a copy.
float PlanePercentile(const cv::Mat& plane, double percentile) {
  std::vector<float> values;
  values.reserve(plane.total());
  for (int y = 0; y < plane.rows; ++y) {
    const float* row = plane.ptr<float>(y);
    values.insert(values.end(), row, row + plane.cols);
  }
  const size_t k = std::min(values.size() - 1,
                            static_cast<size_t>(percentile / 100.0 * (values.size() - 1) + 0.5));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[k];
}

}  // namespace

cv::Rect LargestConcentrationRoi(const cv::Mat& plane, const CropOptions& options) {
  if (plane.type() != CV_32F) {
    PLACEDB_THROW_INVALID("a chromaticity plane must be CV_32FC1 (got ",
                          cv::typeToString(plane.type()), ")");
  }
  if (plane.empty()) return {};
  cv::Mat smooth;
  if (options.smooth_sigma > 0) {
    cv::GaussianBlur(plane, smooth, cv::Size(0, 0), options.smooth_sigma, options.smooth_sigma,
                     cv::BORDER_REFLECT);
  } else {
    smooth = plane;
  }
  const float threshold = PlanePercentile(smooth, options.percentile);
  // Strictly above: a flat plane has no concentration at all.
  cv::Mat mask = smooth > threshold;
  cv::Mat labels, stats, centroids;
  const int count = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  int best = -1;
  int best_area = 0;
  for (int label = 1; label < count; ++label) {  // label 0 is the background
    const int area = stats.at<int>(label, cv::CC_STAT_AREA);
    if (area > best_area) {
      best_area = area;
      best = label;
    }
  }
  if (best < 0 || best_area < options.min_region_pixels) return {};
  cv::Rect box(stats.at<int>(best, cv::CC_STAT_LEFT), stats.at<int>(best, cv::CC_STAT_TOP),
               stats.at<int>(best, cv::CC_STAT_WIDTH), stats.at<int>(best, cv::CC_STAT_HEIGHT));
  box.x -= options.padding;
  box.y -= options.padding;
  box.width += 2 * options.padding;
  box.height += 2 * options.padding;
  return box & cv::Rect(0, 0, plane.cols, plane.rows);
}

CropResult SelectFeatureRichCrop(const cv::Mat& image, const CropOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  if (image.empty()) PLACEDB_THROW_INVALID("cannot crop an empty image");
  CropResult result;
  result.roi = cv::Rect(0, 0, image.cols, image.rows);
  if (image.channels() != 3 || image.depth() != CV_8U) {
    spdlog::warn(
        "feature-rich crop needs an 8-bit colour image (got {} channel(s)); keeping the "
        "whole image",
        image.channels());
    result.fast_keypoints = CountFastKeypoints(image, options.fast_threshold, options.fast_nonmax);
    return result;
  }
  const std::array<cv::Mat, 3> planes = RgChromaticity(image);
  int best = -1;
  for (int c = 0; c < 3; ++c) {
    CropCandidate& candidate = result.candidates[c];
    candidate.roi = LargestConcentrationRoi(planes[c], options);
    if (candidate.roi.empty()) continue;
    candidate.valid = true;
    candidate.fast_keypoints =
        CountFastKeypoints(image(candidate.roi), options.fast_threshold, options.fast_nonmax);
    if (candidate.fast_keypoints < options.min_fast_keypoints) continue;
    if (best < 0) {
      best = c;
      continue;
    }
    const CropCandidate& incumbent = result.candidates[best];
    if (candidate.fast_keypoints > incumbent.fast_keypoints ||
        (candidate.fast_keypoints == incumbent.fast_keypoints &&
         candidate.roi.area() < incumbent.roi.area())) {
      best = c;
    }
  }
  if (best < 0) {
    result.fast_keypoints = CountFastKeypoints(image, options.fast_threshold, options.fast_nonmax);
    return result;
  }
  result.whole_image = false;
  result.channel = best;
  result.roi = result.candidates[best].roi;
  result.fast_keypoints = result.candidates[best].fast_keypoints;
  return result;
}

}  // namespace placedb
