// SURF orientation assignment and descriptor (Haar wavelet responses read
// straight from the integral image). Internal to the SURF module.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "placedb/feature/surf/integral_image.h"

namespace placedb {
namespace surf_internal {

// Scale s of a keypoint of the given size (size 9 <-> s = 1.2).
inline float ScaleOfSize(float size) { return 1.2f * size / 9.0f; }

// Both functions use the AVX2+FMA copy of their loops when the CPU has it
// and the plain copy otherwise, with bit-identical results (surf_simd.h).

// Dominant orientation in degrees in [0, 360) (image axes, y down): Haar
// responses of side 4s at the sample points (i s, j s), i^2 + j^2 < 36,
// weighted by a Gaussian of sigma 2.5 s; the longest sum of the responses
// whose angles fall in a 60-degree window sliding around the circle in
// 3-degree steps. Haar responses are sub-pixel (exact box integrals at
// real-valued positions); descriptor likewise.
// Returns 0 when no sample fits in the image.
float ComputeOrientation(const IntegralImage& ii, const cv::KeyPoint& kp);

// Descriptor of one keypoint (angle used as the orientation, ignored when
// upright): 20s window, 4x4 sub-regions of 5x5 samples, Haar side 2s,
// Gaussian weight sigma 3.3s; per sub-region sum dx, sum dy, sum |dx|,
// sum |dy| (extended: sum dx, sum |dx| split by dy < 0 / dy >= 0 and sum dy,
// sum |dy| split by dx < 0 / dx >= 0); unit L2 norm. out has 64 or 128 floats.
void ComputeDescriptor(const IntegralImage& ii, const cv::KeyPoint& kp, bool upright, bool extended,
                       float* out);

}  // namespace surf_internal
}  // namespace placedb
