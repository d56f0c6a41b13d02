#include "placedb/feature/extractor.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "placedb/util/error.h"

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
  ExtractorOptions no_upscaling;
  no_upscaling.upscale_below = 0;
  const auto extractor = FeatureExtractor::Create(no_upscaling);
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(8, 8), cv::Size(40, 30)}) {
    cv::Mat img(size, CV_8UC3);
    cv::randu(img, 0, 255);
    const FeatureSet set = extractor->Extract(img);
    EXPECT_TRUE(set.empty()) << size;
    EXPECT_EQ(set.descriptors.cols, 32);
  }
  EXPECT_TRUE(extractor->Extract(cv::Mat()).empty());
  // Upscaled at most 4x: 1x1 and 8x8 stay too small for ORB's border.
  const auto upscaling = FeatureExtractor::Create(ExtractorOptions());
  for (const cv::Size size : {cv::Size(1, 1), cv::Size(8, 8)}) {
    cv::Mat img(size, CV_8UC3);
    cv::randu(img, 0, 255);
    EXPECT_TRUE(upscaling->Extract(img).empty()) << size;
  }
  EXPECT_TRUE(upscaling->Extract(cv::Mat()).empty());
}

// Small frames are upscaled for extraction and the keypoints mapped back:
// a 160x120 frame gives far more ORB features (measured 450 vs 130 on image
// 001), every keypoint lies inside the small frame, exactly where the
// features of the 2x image (at upscaled_fast_threshold) are, halved; frames at or above the limit are
// left as they are.
TEST(ExtractorTest, SmallFramesAreUpscaledAndKeypointsMappedBack) {
  const cv::Mat full = cv::imread(PLACEDB_DATA_DIR "/rtabmap_loop/images/001.jpg");
  ASSERT_FALSE(full.empty());
  cv::Mat small;
  cv::resize(full, small, cv::Size(160, 120), 0, 0, cv::INTER_AREA);
  ExtractorOptions off;
  off.upscale_below = 0;
  const FeatureSet plain = FeatureExtractor::Create(off)->Extract(small);
  const FeatureSet up = FeatureExtractor::Create(ExtractorOptions())->Extract(small);  // 240
  std::printf("160x120: %zu features upscaled, %zu without\n", up.size(), plain.size());
  EXPECT_GT(up.size(), 2 * plain.size());
  EXPECT_EQ(up.descriptors.rows, static_cast<int>(up.size()));
  cv::Mat twice;
  cv::resize(small, twice, cv::Size(320, 240), 0, 0, cv::INTER_LINEAR);
  // Upscaled frames use upscaled_fast_threshold (default 5) for FAST.
  ExtractorOptions direct_options = off;
  direct_options.orb.fast_threshold = ExtractorOptions().upscaled_fast_threshold;
  const FeatureSet direct = FeatureExtractor::Create(direct_options)->Extract(twice);
  ASSERT_EQ(direct.size(), up.size());
  for (size_t i = 0; i < up.size(); ++i) {
    const cv::KeyPoint& k = up.keypoints[i];
    EXPECT_GE(k.pt.x, -0.5f);
    EXPECT_LE(k.pt.x, 159.5f);
    EXPECT_GE(k.pt.y, -0.5f);
    EXPECT_LE(k.pt.y, 119.5f);
    EXPECT_NEAR(k.pt.x, (direct.keypoints[i].pt.x + 0.5f) / 2 - 0.5f, 1e-4);
    EXPECT_NEAR(k.pt.y, (direct.keypoints[i].pt.y + 0.5f) / 2 - 0.5f, 1e-4);
    EXPECT_NEAR(k.size, direct.keypoints[i].size / 2, 1e-4);
  }
  EXPECT_EQ(cv::norm(direct.descriptors, up.descriptors, cv::NORM_HAMMING), 0.0);
  // With upscaled_fast_threshold 0 the frame's own threshold (20) applies:
  // fewer corners in the blurred upscaled frame.
  ExtractorOptions same;
  same.upscaled_fast_threshold = 0;
  const FeatureSet at20 = FeatureExtractor::Create(same)->Extract(small);
  std::printf("160x120 upscaled: %zu features at FAST 5, %zu at 20\n", up.size(), at20.size());
  EXPECT_LT(at20.size(), up.size());
  EXPECT_GT(at20.size(), plain.size());
  // 512x384 is above the limit: the same features either way.
  const FeatureSet a = FeatureExtractor::Create(off)->Extract(full);
  const FeatureSet b = FeatureExtractor::Create(ExtractorOptions())->Extract(full);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(cv::norm(a.descriptors, b.descriptors, cv::NORM_HAMMING), 0.0);
}

// Options are range-checked, NaN included, with the field named.
TEST(ExtractorTest, OptionRanges) {
  ExtractorOptions o;
  EXPECT_EQ(o.Check(), "");
  o.orb.edge_threshold = 2147483647;
  EXPECT_NE(o.Check().find("`orb_edge_threshold`"), std::string::npos);
  o = ExtractorOptions();
  o.orb.max_features = 2000000000;
  EXPECT_NE(o.Check().find("`orb_max_features`"), std::string::npos);
  o = ExtractorOptions();
  o.orb.scale_factor = std::nan("");
  EXPECT_NE(o.Check().find("`orb_scale_factor` must be in (1, 4] (got nan)"), std::string::npos);
  o = ExtractorOptions();
  o.upscale_below = -1;
  EXPECT_NE(o.Check().find("upscale_below"), std::string::npos);
  o = ExtractorOptions();
  o.surf.hessian_threshold = std::nan("");
  EXPECT_NE(o.Check().find("`surf_hessian`"), std::string::npos);
  EXPECT_EQ(DescriptorBytes(ExtractorOptions()), 32);
  o = ExtractorOptions();
  o.type = FeatureType::kSurf;
  EXPECT_EQ(DescriptorBytes(o), 256);
  o.surf.extended = true;
  EXPECT_EQ(DescriptorBytes(o), 512);
}

TEST(ExtractorTest, InvalidOptionsThrow) {
  ExtractorOptions options;
  options.orb.scale_factor = 1.0;
  EXPECT_THROW(FeatureExtractor::Create(options), InvalidArgument);
}

}  // namespace
}  // namespace placedb
