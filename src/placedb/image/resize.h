// Resizing of stored keyframe images by an area factor (the paper's 1, 1/4
// and 1/16 of the area: sides x1, x1/2, x1/4).
#pragma once

#include <opencv2/core.hpp>
#include <string>

namespace placedb {

// True for the supported area divisors 1, 4 and 16.
bool IsValidAreaDivisor(int area_divisor);

// Side scale for an area divisor: 1 -> 1, 4 -> 0.5, 16 -> 0.25.
double SideScaleForAreaDivisor(int area_divisor);

// Shrinks `image` to 1/area_divisor of its area with area interpolation
// (sides rounded, at least 1 pixel). Returns the image itself for divisor 1.
cv::Mat ResizeByArea(const cv::Mat& image, int area_divisor);

}  // namespace placedb
