#include "placedb/feature/extractor.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

namespace placedb {
namespace {

TEST(ExtractorTest, OrbOnRealImage) {
  const cv::Mat img = cv::imread(PLACEDB_DATA_DIR "/rtabmap_loop/images/001.jpg");
  ASSERT_FALSE(img.empty());
  const auto extractor = FeatureExtractor::Create(ExtractorOptions());
  const FeatureSet set = extractor->Extract(img);
  EXPECT_EQ(set.type, FeatureType::kOrb);
  EXPECT_GT(set.size(), 300u);
  EXPECT_LE(set.size(), 500u);
  EXPECT_EQ(set.descriptors.rows, static_cast<int>(set.size()));
  EXPECT_EQ(set.descriptors.cols, 32);
  EXPECT_EQ(set.descriptors.type(), CV_8U);
  // Deterministic.
  const FeatureSet again = extractor->Extract(img);
  ASSERT_EQ(again.size(), set.size());
  EXPECT_EQ(cv::norm(again.descriptors, set.descriptors, cv::NORM_HAMMING), 0.0);
}

TEST(ExtractorTest, TinyAndEmptyImagesGiveNoFeatures) {
  const auto extractor = FeatureExtractor::Create(ExtractorOptions());
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(8, 8), cv::Size(40, 30)}) {
    cv::Mat img(size, CV_8UC3);
    cv::randu(img, 0, 255);
    const FeatureSet set = extractor->Extract(img);
    EXPECT_TRUE(set.empty()) << size;
    EXPECT_EQ(set.descriptors.cols, 32);
  }
  EXPECT_TRUE(extractor->Extract(cv::Mat()).empty());
}

TEST(ExtractorTest, InvalidOptionsThrow) {
  ExtractorOptions options;
  options.orb.scale_factor = 1.0;
  EXPECT_THROW(FeatureExtractor::Create(options), std::invalid_argument);
}

}  // namespace
}  // namespace placedb
