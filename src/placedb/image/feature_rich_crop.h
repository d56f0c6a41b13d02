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
#include "placedb/image/crop_options.h"

namespace placedb {

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
