#include "placedb/feature/extractor.h"

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "placedb/image/chromaticity.h"
#include "placedb/util/check.h"

namespace placedb {

std::string OrbOptions::Check() const {
  if (max_features < 1) return "orb.max_features must be >= 1";
  if (scale_factor <= 1.0) return "orb.scale_factor must be > 1";
  if (num_levels < 1) return "orb.num_levels must be >= 1";
  if (edge_threshold < 0) return "orb.edge_threshold must be >= 0";
  if (fast_threshold < 1 || fast_threshold > 255) return "orb.fast_threshold must be in [1, 255]";
  if (patch_size < 2) return "orb.patch_size must be >= 2";
  return "";
}

std::string ExtractorOptions::Check() const {
  if (type == FeatureType::kOrb) return orb.Check();
  if (type == FeatureType::kSurf) return surf.Check();
  return "unknown feature type";
}

namespace {

class OrbExtractor : public FeatureExtractor {
 public:
  explicit OrbExtractor(const OrbOptions& options)
      : edge_threshold_(options.edge_threshold),
        orb_(cv::ORB::create(options.max_features, static_cast<float>(options.scale_factor),
                             options.num_levels, options.edge_threshold, 0, 2,
                             cv::ORB::HARRIS_SCORE, options.patch_size, options.fast_threshold)) {}

  FeatureSet Extract(const cv::Mat& image) const override {
    FeatureSet set;
    set.type = FeatureType::kOrb;
    set.descriptors = cv::Mat(0, 32, CV_8U);
    const cv::Mat gray = ToGray(image);
    // ORB keeps no keypoint within edge_threshold of the border (and OpenCV
    // fails on images smaller than that): such images have no features.
    if (gray.cols <= 2 * edge_threshold_ || gray.rows <= 2 * edge_threshold_) return set;
    cv::Mat descriptors;
    orb_->detectAndCompute(gray, cv::noArray(), set.keypoints, descriptors);
    if (!set.keypoints.empty()) set.descriptors = descriptors;
    return set;
  }
  FeatureType type() const override { return FeatureType::kOrb; }

 private:
  int edge_threshold_;
  cv::Ptr<cv::ORB> orb_;
};

class SurfExtractor : public FeatureExtractor {
 public:
  explicit SurfExtractor(const SurfOptions& options) : options_(options) {}

  FeatureSet Extract(const cv::Mat& image) const override {
    FeatureSet set;
    set.type = FeatureType::kSurf;
    set.descriptors = cv::Mat(0, options_.extended ? 128 : 64, CV_32F);
    const cv::Mat gray = ToGray(image);
    if (gray.empty()) return set;
    cv::Mat descriptors;
    DetectAndComputeSurf(gray, options_, &set.keypoints, &descriptors);
    if (!set.keypoints.empty()) set.descriptors = descriptors;
    return set;
  }
  FeatureType type() const override { return FeatureType::kSurf; }

 private:
  SurfOptions options_;
};

}  // namespace

std::unique_ptr<FeatureExtractor> FeatureExtractor::Create(const ExtractorOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  switch (options.type) {
    case FeatureType::kOrb:
      return std::make_unique<OrbExtractor>(options.orb);
    case FeatureType::kSurf:
      return std::make_unique<SurfExtractor>(options.surf);
  }
  PLACEDB_THROW_INVALID("unknown feature type");
}

}  // namespace placedb
