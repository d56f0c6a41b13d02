#include "placedb/image/resize.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "placedb/util/check.h"

namespace placedb {

bool IsValidAreaDivisor(int area_divisor) {
  return area_divisor == 1 || area_divisor == 4 || area_divisor == 16;
}

double SideScaleForAreaDivisor(int area_divisor) {
  if (!IsValidAreaDivisor(area_divisor)) {
    PLACEDB_THROW_INVALID("`resize` must be 1, 4 or 16 (got ", area_divisor, ")");
  }
  return 1.0 / std::sqrt(static_cast<double>(area_divisor));
}

cv::Mat ResizeByArea(const cv::Mat& image, int area_divisor) {
  const double scale = SideScaleForAreaDivisor(area_divisor);
  if (area_divisor == 1 || image.empty()) return image;
  const cv::Size size(std::max(1, static_cast<int>(std::lround(image.cols * scale))),
                      std::max(1, static_cast<int>(std::lround(image.rows * scale))));
  cv::Mat out;
  cv::resize(image, out, size, 0, 0, cv::INTER_AREA);
  return out;
}

}  // namespace placedb
