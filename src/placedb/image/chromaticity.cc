#include "placedb/image/chromaticity.h"

#include <opencv2/imgproc.hpp>

#include "placedb/util/check.h"

namespace placedb {

const char* ChromaChannelName(ChromaChannel channel) {
  switch (channel) {
    case ChromaChannel::kRed:
      return "red";
    case ChromaChannel::kGreen:
      return "green";
    case ChromaChannel::kBlue:
      return "blue";
  }
  return "unknown";
}

std::array<cv::Mat, 3> RgChromaticity(const cv::Mat& bgr) {
  if (bgr.type() != CV_8UC3) {
    PLACEDB_THROW_INVALID("rg-chromaticity needs an 8-bit BGR image (got ",
                          cv::typeToString(bgr.type()), ")");
  }
  std::array<cv::Mat, 3> planes;
  for (auto& p : planes) p.create(bgr.size(), CV_32F);
  for (int y = 0; y < bgr.rows; ++y) {
    const uint8_t* src = bgr.ptr<uint8_t>(y);
    float* r = planes[0].ptr<float>(y);
    float* g = planes[1].ptr<float>(y);
    float* b = planes[2].ptr<float>(y);
    for (int x = 0; x < bgr.cols; ++x) {
      const float B = src[3 * x], G = src[3 * x + 1], R = src[3 * x + 2];
      const float sum = R + G + B;
      if (sum <= 0.f) {
        r[x] = g[x] = b[x] = 1.f / 3.f;
      } else {
        const float inv = 1.f / sum;
        r[x] = R * inv;
        g[x] = G * inv;
        b[x] = B * inv;
      }
    }
  }
  return planes;
}

cv::Mat ToGray(const cv::Mat& image) {
  if (!image.empty() && image.depth() != CV_8U) {
    PLACEDB_THROW_INVALID("an 8-bit image is needed (got ", cv::typeToString(image.type()), ")");
  }
  if (image.empty() || image.channels() == 1) return image;
  cv::Mat gray;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  } else {
    PLACEDB_THROW_INVALID("unsupported number of channels: ", image.channels());
  }
  return gray;
}

}  // namespace placedb
