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
  // Most keypoints kept per image (strongest by Harris score). Range
  // [1, 100000]. Default 500.
  int max_features = 500;
  // Pyramid decimation ratio between levels. Range (1, 4]. Default 1.2.
  double scale_factor = 1.2;
  // Number of pyramid levels. Range [1, 32]. Default 8.
  int num_levels = 8;
  // Border without features, pixels (should match patch_size). Range
  // [0, 512]. Default 31.
  int edge_threshold = 31;
  // FAST threshold used by ORB's detector. Range [1, 255]. Default 20.
  int fast_threshold = 20;
  // Size of the BRIEF patch, pixels. Range [2, 512]. Default 31.
  int patch_size = 31;

  std::string Check() const;
};

struct ExtractorOptions {
  // Which descriptor to compute. Default ORB.
  FeatureType type = FeatureType::kOrb;
  OrbOptions orb;
  SurfOptions surf;
  // Small frames: an image whose shorter side is below this many pixels is
  // upscaled (bilinear) until it is this long (at most 4x) for extraction,
  // and the keypoints are mapped back to the image (position, size). ORB's 31-px
  // patch and border leave little of a 160x120 frame. 0 disables. Range
  // [0, 4096]. Default 240 (measured on data/rtabmap_loop shrunk to 160x120:
  // recall@1 0.909 without, 0.977 with; 320x240 frames are not upscaled).
  int upscale_below = 240;

  std::string Check() const;
};

// Bytes per descriptor row the options produce: 32 (ORB), 256 or 512 (SURF).
int DescriptorBytes(const ExtractorOptions& options);

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
