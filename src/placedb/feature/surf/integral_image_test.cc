#include "placedb/feature/surf/integral_image.h"

#include <gtest/gtest.h>

#include <random>

namespace placedb {
namespace surf_internal {
namespace {

TEST(IntegralImageTest, BoxSumsMatchBruteForce) {
  cv::Mat img(37, 53, CV_8UC1);
  cv::RNG rng(7);
  rng.fill(img, cv::RNG::UNIFORM, 0, 256);
  const IntegralImage ii(img);
  ASSERT_EQ(ii.rows(), 37);
  ASSERT_EQ(ii.cols(), 53);
  std::mt19937 gen(3);
  for (int t = 0; t < 500; ++t) {
    int r0 = gen() % 38, r1 = gen() % 38, c0 = gen() % 54, c1 = gen() % 54;
    if (r0 > r1) std::swap(r0, r1);
    if (c0 > c1) std::swap(c0, c1);
    int64_t want = 0;
    for (int r = r0; r < r1; ++r) {
      for (int c = c0; c < c1; ++c) want += img.at<uint8_t>(r, c);
    }
    ASSERT_EQ(ii.BoxSum(r0, c0, r1, c1), want) << r0 << " " << c0 << " " << r1 << " " << c1;
  }
}

TEST(IntegralImageTest, EmptyImage) {
  const IntegralImage ii((cv::Mat()));
  EXPECT_EQ(ii.rows(), 0);
  EXPECT_EQ(ii.cols(), 0);
  EXPECT_EQ(ii.BoxSum(0, 0, 0, 0), 0);
}

TEST(IntegralImageTest, BoxSumsStayExactWhenTheTableWraps) {
  // 4200 x 4200 white pixels sum to 4.5e9 > 2^32: the table wraps, box sums
  // must not.
  const cv::Mat img(4200, 4200, CV_8UC1, cv::Scalar(255));
  const IntegralImage ii(img);
  EXPECT_EQ(ii.BoxSum(4100, 4100, 4200, 4200), 255 * 100 * 100);
  EXPECT_EQ(ii.BoxSum(0, 0, 10, 10), 255 * 100);
  EXPECT_EQ(ii.BoxSum(2000, 4000, 4000, 4200), 255 * 2000 * 200);
}

}  // namespace
}  // namespace surf_internal
}  // namespace placedb
