#include "placedb/image/chromaticity.h"

#include <gtest/gtest.h>

#include "placedb/util/error.h"

namespace placedb {
namespace {

TEST(ChromaticityTest, KnownPixels) {
  cv::Mat img(1, 3, CV_8UC3);
  img.at<cv::Vec3b>(0, 0) = cv::Vec3b(0, 0, 0);     // black
  img.at<cv::Vec3b>(0, 1) = cv::Vec3b(10, 30, 60);  // B G R
  img.at<cv::Vec3b>(0, 2) = cv::Vec3b(0, 0, 200);   // pure red
  const auto planes = RgChromaticity(img);
  EXPECT_FLOAT_EQ(planes[0].at<float>(0, 0), 1.f / 3.f);
  EXPECT_FLOAT_EQ(planes[1].at<float>(0, 0), 1.f / 3.f);
  EXPECT_FLOAT_EQ(planes[2].at<float>(0, 0), 1.f / 3.f);
  EXPECT_FLOAT_EQ(planes[0].at<float>(0, 1), 0.6f);
  EXPECT_FLOAT_EQ(planes[1].at<float>(0, 1), 0.3f);
  EXPECT_FLOAT_EQ(planes[2].at<float>(0, 1), 0.1f);
  EXPECT_FLOAT_EQ(planes[0].at<float>(0, 2), 1.f);
  EXPECT_FLOAT_EQ(planes[2].at<float>(0, 2), 0.f);
}

TEST(ChromaticityTest, RejectsGray) {
  EXPECT_THROW(RgChromaticity(cv::Mat(4, 4, CV_8UC1, cv::Scalar(3))), InvalidArgument);
}

}  // namespace
}  // namespace placedb
