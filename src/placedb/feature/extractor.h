// Feature extraction behind one interface, chosen by a factory from options.
#pragma once

#include <memory>
#include <opencv2/core.hpp>
#include <string>

#include "placedb/feature/surf/surf.h"
#include "placedb/feature/types.h"

namespace placedb {

// OpenCV ORB's settings (defaults equal to cv::ORB::create()'s).
struct OrbOptions {
  // Most keypoints kept per image (strongest by Harris score). Default 500.
  int max_features = 500;
  // Pyramid decimation ratio between levels, > 1. Default 1.2.
  double scale_factor = 1.2;
  // Number of pyramid levels. Default 8.
  int num_levels = 8;
  // Border without features, pixels (should match patch_size). Default 31.
  int edge_threshold = 31;
  // FAST threshold used by ORB's detector. Default 20.
  int fast_threshold = 20;
  // Size of the BRIEF patch, pixels. Default 31.
  int patch_size = 31;

  std::string Check() const;
};

struct ExtractorOptions {
  // Which descriptor to compute. Default ORB.
  FeatureType type = FeatureType::kOrb;
  OrbOptions orb;
  SurfOptions surf;

  std::string Check() const;
};

class FeatureExtractor {
 public:
  virtual ~FeatureExtractor() = default;

  // Keypoints and descriptors of an 8-bit gray or BGR image. Images too small
  // to hold a feature give an empty set, never an error.
  virtual FeatureSet Extract(const cv::Mat& image) const = 0;
  virtual FeatureType type() const = 0;

  // The concrete extractor for `options.type`.
  static std::unique_ptr<FeatureExtractor> Create(const ExtractorOptions& options);
};

}  // namespace placedb
