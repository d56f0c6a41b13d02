// rg-chromaticity: each channel's share of the pixel's total intensity.
#pragma once

#include <array>
#include <opencv2/core.hpp>

namespace placedb {

// Channel order of the chromaticity planes (not OpenCV's BGR order).
enum class ChromaChannel : int { kRed = 0, kGreen = 1, kBlue = 2 };
const char* ChromaChannelName(ChromaChannel channel);

// Splits a BGR CV_8UC3 image into three CV_32F planes r, g, b with
// r = R / (R + G + B), etc. A black pixel (R + G + B = 0) has r = g = b = 1/3.
// Throws InvalidArgument for any other image type.
std::array<cv::Mat, 3> RgChromaticity(const cv::Mat& bgr);

// Converts an 8-bit image with 1, 3 (BGR) or 4 (BGRA) channels to gray; a
// gray image is returned as is (no copy). Throws InvalidArgument for
// other depths or channel counts.
cv::Mat ToGray(const cv::Mat& image);

}  // namespace placedb
