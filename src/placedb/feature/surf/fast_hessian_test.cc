#include "placedb/feature/surf/fast_hessian.h"

#include <gtest/gtest.h>

#include <cmath>

namespace placedb {
namespace surf_internal {
namespace {

// A Gaussian blob of standard deviation sigma centred at (cx, cy).
cv::Mat Blob(int rows, int cols, double cx, double cy, double sigma, bool bright) {
  cv::Mat img(rows, cols, CV_8UC1);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const double d2 = (c - cx) * (c - cx) + (r - cy) * (r - cy);
      const double g = std::exp(-d2 / (2 * sigma * sigma));
      img.at<uint8_t>(r, c) = cv::saturate_cast<uint8_t>(bright ? 40 + 200 * g : 240 - 200 * g);
    }
  }
  return img;
}

TEST(HessianFilterTest, GeometryFollowsThePaper) {
  // 9x9: lobes 3 wide, 5 long; Dxy lobes 3x3 with a one-pixel gap.
  const HessianFilter f9(0, 0);
  EXPECT_EQ(f9.size, 9);
  EXPECT_EQ(f9.lobe, 3);
  EXPECT_EQ(f9.lobe_len, 5);
  EXPECT_EQ(f9.lobe_off, 2);
  EXPECT_EQ(f9.dxy_lo, 1);
  EXPECT_EQ(f9.dxy_hi, 5);
  // 15x15: lobes 5 x 9; 27x27: 9 x 17.
  const HessianFilter f15(0, 1);
  EXPECT_EQ(f15.size, 15);
  EXPECT_EQ(f15.lobe, 5);
  EXPECT_EQ(f15.lobe_len, 9);
  EXPECT_EQ(f15.dxy_lo + f15.lobe + 1, f15.dxy_hi);
  const HessianFilter f27(0, 3);
  EXPECT_EQ(f27.lobe, 9);
  EXPECT_EQ(f27.lobe_len, 17);
  // Second octave: twice the first octave's filters.
  const HessianFilter f18(1, 0);
  EXPECT_EQ(f18.size, 18);
  EXPECT_EQ(f18.lobe, 6);
  EXPECT_EQ(f18.lobe_len, 10);
}

TEST(HessianFilterTest, FlatImageHasZeroResponse) {
  const cv::Mat img(40, 40, CV_8UC1, cv::Scalar(77));
  const IntegralImage ii(img);
  float dxx, dyy, dxy;
  HessianFilter(0, 2).Responses(ii, 5, 7, &dxx, &dyy, &dxy);
  EXPECT_EQ(dxx, 0.f);
  EXPECT_EQ(dyy, 0.f);
  EXPECT_EQ(dxy, 0.f);
}

TEST(HessianFilterTest, HorizontalRampHasNoSecondDerivative) {
  cv::Mat img(40, 40, CV_8UC1);
  for (int r = 0; r < 40; ++r) {
    for (int c = 0; c < 40; ++c) img.at<uint8_t>(r, c) = static_cast<uint8_t>(3 * c + r);
  }
  const IntegralImage ii(img);
  float dxx, dyy, dxy;
  HessianFilter(0, 1).Responses(ii, 3, 4, &dxx, &dyy, &dxy);
  EXPECT_EQ(dxx, 0.f);
  EXPECT_EQ(dyy, 0.f);
  EXPECT_EQ(dxy, 0.f);
}

// The detected scale is proportional to the blob's size (scale covariance):
// with our filters s = 1.2 size / 9 comes out at about 0.7 sigma.
TEST(DetectFastHessianTest, FindsGaussianBlobAtItsCentreAndScale) {
  for (const bool bright : {true, false}) {
    for (const double sigma : {2.5, 4.0, 8.0}) {
      const double cx = 100.3, cy = 90.6;
      const IntegralImage ii(Blob(200, 220, cx, cy, sigma, bright));
      std::vector<cv::KeyPoint> kps;
      DetectFastHessian(ii, 100.0, 4, 3, &kps);
      ASSERT_FALSE(kps.empty()) << "sigma " << sigma;
      const auto best = std::max_element(
          kps.begin(), kps.end(),
          [](const cv::KeyPoint& a, const cv::KeyPoint& b) { return a.response < b.response; });
      const double scale = 1.2 * best->size / 9.0;
      std::printf("blob sigma %.1f %s: kp (%.2f, %.2f) size %.1f scale %.2f response %.0f\n", sigma,
                  bright ? "bright" : "dark", best->pt.x, best->pt.y, best->size, scale,
                  best->response);
      EXPECT_NEAR(best->pt.x, cx, 0.1 * sigma + 0.5);
      EXPECT_NEAR(best->pt.y, cy, 0.1 * sigma + 0.5);
      EXPECT_NEAR(scale / sigma, 0.7, 0.1);
      // A bright blob has a negative Laplacian.
      EXPECT_EQ(best->class_id, bright ? -1 : 1);
    }
  }
}

}  // namespace
}  // namespace surf_internal
}  // namespace placedb
