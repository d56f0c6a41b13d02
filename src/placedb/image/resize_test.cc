#include "placedb/image/resize.h"

#include <gtest/gtest.h>

#include "placedb/util/error.h"

namespace placedb {
namespace {

TEST(ResizeTest, AreaFactors) {
  cv::Mat img(384, 512, CV_8UC3, cv::Scalar(1, 2, 3));
  EXPECT_EQ(ResizeByArea(img, 1).size(), cv::Size(512, 384));
  EXPECT_EQ(ResizeByArea(img, 4).size(), cv::Size(256, 192));
  EXPECT_EQ(ResizeByArea(img, 16).size(), cv::Size(128, 96));
  EXPECT_DOUBLE_EQ(SideScaleForAreaDivisor(16), 0.25);
  // Area interpolation preserves a flat colour exactly.
  EXPECT_EQ(ResizeByArea(img, 16).at<cv::Vec3b>(5, 5), cv::Vec3b(1, 2, 3));
}

TEST(ResizeTest, TinyImagesStayAtLeastOnePixel) {
  cv::Mat img(2, 3, CV_8UC1, cv::Scalar(9));
  EXPECT_EQ(ResizeByArea(img, 16).size(), cv::Size(1, 1));
}

TEST(ResizeTest, RejectsOtherFactors) {
  EXPECT_THROW(ResizeByArea(cv::Mat(4, 4, CV_8UC1), 2), InvalidArgument);
  EXPECT_FALSE(IsValidAreaDivisor(9));
}

}  // namespace
}  // namespace placedb
