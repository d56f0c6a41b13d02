#include "placedb/feature/surf/integral_image.h"

#include "placedb/util/check.h"

namespace placedb {
namespace surf_internal {

IntegralImage::IntegralImage(const cv::Mat& gray) {
  // SURF's ToGray made `gray`: 8-bit, one channel.
  PLACEDB_CHECK(gray.empty() || gray.type() == CV_8UC1, "an integral image of ",
                cv::typeToString(gray.type()));
  rows_ = gray.rows;
  cols_ = gray.cols;
  stride_ = cols_ + 1;
  data_.assign(static_cast<size_t>(rows_ + 1) * stride_, 0u);
  for (int r = 0; r < rows_; ++r) {
    const uint8_t* src = gray.ptr<uint8_t>(r);
    const uint32_t* above = Row(r);
    uint32_t* out = data_.data() + static_cast<size_t>(r + 1) * stride_;
    uint32_t row_sum = 0;
    for (int c = 0; c < cols_; ++c) {
      row_sum += src[c];
      out[c + 1] = above[c + 1] + row_sum;
    }
  }
}

}  // namespace surf_internal
}  // namespace placedb
