// The options of the paper's feature-rich crop (part of the public face,
// placedb/placedb.h; the crop itself is image/feature_rich_crop.h).
#pragma once

#include <string>

#include "placedb/util/option_table.h"

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

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<CropOptions>& Table();
  std::string Check() const;
};

}  // namespace placedb
