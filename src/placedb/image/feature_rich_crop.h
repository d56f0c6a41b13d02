// The paper's feature-rich cropping (Benavidez et al. 2014, section II.A), as
// ARCHITECTURE.md reads it: for each rg-chromaticity channel, the bounding box
// of the largest region where that channel is concentrated; FAST runs on each
// candidate crop of the original image; a candidate qualifies with at least
// `min_fast_keypoints` corners; the qualifying one with the most corners wins
// (ties: the smaller crop); when none qualifies the whole image is kept.
#pragma once

#include <array>
#include <opencv2/core.hpp>
#include <string>

#include "placedb/image/chromaticity.h"

namespace placedb {

struct CropOptions {
  // Standard deviation of the Gaussian that smooths each chromaticity plane
  // before thresholding, pixels. 0 disables smoothing. Range [0, 50].
  // Default 2.
  double smooth_sigma = 2.0;
  // A pixel belongs to a channel's concentration when its smoothed value is
  // above this percentile of the plane. Range [0, 99.9]. Default 85 (measured on
  // data/rtabmap_loop: 85 keeps recall@1 at 0.95 with 63% less image data;
  // 90 saves 69% at recall 0.91; 80 saves 53% at 0.95).
  double percentile = 85.0;
  // Pixels added on every side of a region's bounding box (clamped to the
  // image), so that features on the region's edge keep their surroundings.
  // Range [0, 4096]. Default 16.
  int padding = 16;
  // A candidate needs at least this many FAST corners to qualify (the paper's
  // empirical threshold). Range [0, 100000]. Default 15.
  int min_fast_keypoints = 15;
  // FAST intensity threshold (OpenCV's default). Range [1, 255]. Default 10.
  int fast_threshold = 10;
  // FAST non-maximum suppression (OpenCV's default). Default true.
  bool fast_nonmax = true;
  // Regions smaller than this many pixels never become candidates. Range
  // [1, 1e8]. Default 16.
  int min_region_pixels = 16;

  std::string Check() const;
};

// What the selection looked at for one channel.
struct CropCandidate {
  bool valid = false;      // false when the channel had no concentrated region
  cv::Rect roi;            // in the input image
  int fast_keypoints = 0;  // FAST corners counted on the crop
};

struct CropResult {
  cv::Rect roi;                             // the kept region (the whole image when no winner)
  bool whole_image = true;                  // true when no candidate qualified
  int channel = -1;                         // winning ChromaChannel, -1 for the whole image
  int fast_keypoints = 0;                   // FAST corners on the kept region
  std::array<CropCandidate, 3> candidates;  // r, g, b
};

// Counts FAST corners on an 8-bit image (gray or BGR; BGR is converted).
int CountFastKeypoints(const cv::Mat& image, int threshold, bool nonmax);

// The region of the largest concentration of one chromaticity plane (CV_32F),
// or an empty rect when there is none (a flat plane).
cv::Rect LargestConcentrationRoi(const cv::Mat& plane, const CropOptions& options);

// Chooses the feature-rich crop of `image`. A single-channel image cannot be
// split into chromaticities: the whole image is kept and a warning logged.
CropResult SelectFeatureRichCrop(const cv::Mat& image, const CropOptions& options);

}  // namespace placedb
