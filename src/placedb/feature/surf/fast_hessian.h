// The Fast-Hessian detector of SURF: box-filter approximations of the
// second-order Gaussian derivatives evaluated on an integral image over
// octaves and layers, 3x3x3 non-maximum suppression, and quadratic
// interpolation of position and scale. Internal to the SURF module.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "placedb/feature/surf/integral_image.h"

namespace placedb {
namespace surf_internal {

// Geometry of the three box filters (Dxx, Dyy, Dxy) of one filter size.
// The filter of side size() anchored at cell (r, c) of a layer sampled every
// step() pixels has its top-left pixel at (r * step - size / 2, c * step -
// size / 2).
struct HessianFilter {
  // size = (9 + 6 * layer) << octave.
  HessianFilter(int octave, int layer);

  int size = 0;
  int lobe = 0;           // Width w of a Dxx lobe (= side of a Dxy lobe).
  int lobe_len = 0;       // Length of a Dxx lobe (2w - 1 at octave 0, scaled).
  int lobe_off = 0;       // Offset of the Dxx lobes across the filter.
  int dxy_lo = 0;         // First pixel of the first Dxy lobe.
  int dxy_hi = 0;         // First pixel of the second Dxy lobe.
  float inv_area_xx = 0;  // 1 / (lobe * lobe_len).
  float inv_area_xy = 0;  // 1 / (lobe * lobe).

  // Box-mean responses with the filter's top-left pixel at (top, left); the
  // filter must lie inside the image.
  void Responses(const IntegralImage& ii, int top, int left, float* dxx, float* dyy,
                 float* dxy) const;
};

// Appends the Fast-Hessian keypoints of the image (see surf.h for the fields;
// angle is left at -1). threshold: minimum determinant.
void DetectFastHessian(const IntegralImage& ii, double threshold, int num_octaves,
                       int num_octave_layers, std::vector<cv::KeyPoint>* keypoints);

}  // namespace surf_internal
}  // namespace placedb
