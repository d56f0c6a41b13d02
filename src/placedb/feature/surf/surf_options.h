// The options of our SURF (part of the public face, placedb/placedb.h).
#pragma once

#include <string>

#include "placedb/util/option_table.h"

namespace placedb {

struct SurfOptions {
  // Minimum Hessian determinant of a kept extremum, in squared grey levels
  // (box means of a 0..255 image; same scale as OpenCV's SURF). Range
  // [0, 1e6]. Default 100.
  double hessian_threshold = 100.0;
  // Number of octaves (each doubles the filter sizes and the sampling step).
  // Default 4, range 1..8.
  int num_octaves = 4;
  // Layers per octave in which extrema are searched (OpenCV's nOctaveLayers);
  // each octave computes num_octave_layers + 2 filter sizes. Default 3,
  // range 1..8.
  int num_octave_layers = 3;
  // Extended 128-d descriptor (sums split by the sign of the other
  // derivative) instead of 64-d. Default false.
  bool extended = false;
  // U-SURF: skip the orientation, every keypoint gets angle 0 and its
  // descriptor is computed in the image axes. Default false.
  bool upright = false;
  // Keep only the this many strongest keypoints (by response); 0 keeps all.
  // Range [0, 1000000]. Default 0.
  int max_features = 0;

  // "" when valid, else the reason.
  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<SurfOptions>& Table();
  std::string Check() const;
};

}  // namespace placedb
