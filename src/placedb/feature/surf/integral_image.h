// Integral image of an 8-bit grey image, stored as uint32 with wrap-around.
//
// Entry (r, c) is the sum of the pixels in rows [0, r) and columns [0, c), so
// the table is (rows + 1) x (cols + 1) with a zero first row and column. The
// running sums may wrap modulo 2^32 on very large images, but a box sum
// computed with unsigned (modular) arithmetic is still exact as long as the
// box itself sums to less than 2^31 (boxes up to ~8.4 Mpixel of white), so the
// 32-bit table is safe for any image size SURF uses.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

namespace placedb {
namespace surf_internal {

class IntegralImage {
 public:
  // gray: CV_8UC1 (may be empty).
  explicit IntegralImage(const cv::Mat& gray);

  int rows() const { return rows_; }      // Image rows (the table has rows + 1).
  int cols() const { return cols_; }      // Image columns.
  int stride() const { return stride_; }  // Elements per table row.

  const uint32_t* Row(int r) const { return data_.data() + static_cast<size_t>(r) * stride_; }
  const uint32_t* data() const { return data_.data(); }

  // Sum of pixels in rows [r0, r1), columns [c0, c1); requires
  // 0 <= r0 <= r1 <= rows(), 0 <= c0 <= c1 <= cols().
  int32_t BoxSum(int r0, int c0, int r1, int c1) const {
    const uint32_t* a = Row(r0);
    const uint32_t* b = Row(r1);
    return static_cast<int32_t>(b[c1] - b[c0] - a[c1] + a[c0]);
  }

 private:
  int rows_ = 0;
  int cols_ = 0;
  int stride_ = 1;
  std::vector<uint32_t> data_;
};

}  // namespace surf_internal
}  // namespace placedb
