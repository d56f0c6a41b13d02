#include "placedb/image/feature_rich_crop.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "placedb/util/error.h"

namespace placedb {
namespace {

// Grey background with faint noise (too weak for FAST), so no channel has a
// concentration outside the patches drawn on it.
cv::Mat NoisyGrey(int rows, int cols, uint64_t seed) {
  cv::Mat img(rows, cols, CV_8UC3, cv::Scalar(128, 128, 128));
  cv::Mat noise(rows, cols, CV_8UC3);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 3);
  img += noise;
  return img;
}

// Fills `patch` with random overlapping discs of one colour channel at
// varying intensity: chromaticity 1 for that channel and many FAST corners.
// (Axis-aligned blocks would not do: their equal FAST scores cancel out in
// non-maximum suppression.)
void DrawTexturedPatch(cv::Mat& img, const cv::Rect& patch, int bgr_channel, uint64_t seed) {
  cv::RNG rng(seed);
  cv::Mat roi = img(patch);
  cv::Scalar base(0, 0, 0);
  base[bgr_channel] = 100;
  roi.setTo(base);
  const int discs = patch.area() / 40;
  for (int i = 0; i < discs; ++i) {
    cv::Scalar colour(0, 0, 0);
    colour[bgr_channel] = rng.uniform(40, 256);
    cv::circle(roi, cv::Point(rng.uniform(0, patch.width), rng.uniform(0, patch.height)),
               rng.uniform(2, 7), colour, cv::FILLED, cv::LINE_8);
  }
}

void DrawTexturedRedPatch(cv::Mat& img, const cv::Rect& patch, uint64_t seed) {
  DrawTexturedPatch(img, patch, 2, seed);
}

TEST(FeatureRichCropTest, TexturedRedPatchOnGreyIsFound) {
  cv::Mat img = NoisyGrey(480, 640, 1);
  const cv::Rect patch(200, 150, 120, 90);
  DrawTexturedRedPatch(img, patch, 2);
  const CropOptions options;
  const CropResult r = SelectFeatureRichCrop(img, options);
  EXPECT_FALSE(r.whole_image);
  EXPECT_EQ(r.channel, static_cast<int>(ChromaChannel::kRed));
  // The red ROI covers the patch, and not much more (the smoothing blurs the
  // border by a few pixels).
  EXPECT_EQ((r.roi & patch), patch) << r.roi;
  EXPECT_LE(r.roi.width, patch.width + 2 * options.padding + 40) << r.roi;
  EXPECT_LE(r.roi.height, patch.height + 2 * options.padding + 40) << r.roi;
  // Without padding the box hugs the patch (smoothing and the grey noise next to it add up to ~20
  // px).
  CropOptions tight = options;
  tight.padding = 0;
  const CropResult t = SelectFeatureRichCrop(img, tight);
  EXPECT_EQ((t.roi & patch), patch) << t.roi;
  EXPECT_LE(t.roi.width, patch.width + 40) << t.roi;
  EXPECT_LE(t.roi.height, patch.height + 40) << t.roi;
  EXPECT_GE(r.fast_keypoints, 15);
  EXPECT_TRUE(r.candidates[0].valid);
  // The kept crop is far smaller than the image: the point of the method.
  EXPECT_LT(r.roi.area(), img.rows * img.cols / 10);
}

TEST(FeatureRichCropTest, FlatImageKeepsWholeImage) {
  cv::Mat img(240, 320, CV_8UC3, cv::Scalar(40, 90, 200));
  const CropResult r = SelectFeatureRichCrop(img, CropOptions());
  EXPECT_TRUE(r.whole_image);
  EXPECT_EQ(r.channel, -1);
  EXPECT_EQ(r.roi, cv::Rect(0, 0, 320, 240));
  for (const auto& c : r.candidates) EXPECT_FALSE(c.valid);
}

TEST(FeatureRichCropTest, FeaturelessColourPatchDoesNotQualify) {
  // A flat red patch is a concentration of red, but FAST finds no corner
  // inside its crop (its corners lie on the crop's border): fewer than 15, so
  // the whole image is kept.
  cv::Mat img = NoisyGrey(240, 320, 3);
  img(cv::Rect(100, 80, 60, 50)).setTo(cv::Scalar(0, 0, 200));
  const CropResult r = SelectFeatureRichCrop(img, CropOptions());
  EXPECT_TRUE(r.candidates[0].valid);
  EXPECT_LT(r.candidates[0].fast_keypoints, 15);
  EXPECT_TRUE(r.whole_image);
  EXPECT_EQ(r.roi, cv::Rect(0, 0, 320, 240));
}

TEST(FeatureRichCropTest, ThresholdIsAnOption) {
  cv::Mat img = NoisyGrey(480, 640, 1);
  DrawTexturedRedPatch(img, cv::Rect(200, 150, 120, 90), 2);
  CropOptions options;
  const CropResult found = SelectFeatureRichCrop(img, options);
  ASSERT_FALSE(found.whole_image);
  // Demand one corner more than the red crop has: nothing qualifies.
  options.min_fast_keypoints = found.fast_keypoints + 1;
  const CropResult none = SelectFeatureRichCrop(img, options);
  EXPECT_TRUE(none.whole_image);
  EXPECT_EQ(none.channel, -1);
}

TEST(FeatureRichCropTest, MostFeaturesWinsAmongQualifyingChannels) {
  cv::Mat img = NoisyGrey(480, 640, 4);
  // A small textured red patch and a larger textured blue patch: blue has
  // more FAST corners and wins.
  DrawTexturedRedPatch(img, cv::Rect(40, 40, 60, 60), 5);
  const cv::Rect big(300, 200, 200, 150);
  DrawTexturedPatch(img, big, 0, 7);
  const CropResult r = SelectFeatureRichCrop(img, CropOptions());
  ASSERT_FALSE(r.whole_image);
  EXPECT_EQ(r.channel, static_cast<int>(ChromaChannel::kBlue));
  EXPECT_GT(r.candidates[2].fast_keypoints, r.candidates[0].fast_keypoints);
  EXPECT_EQ((r.roi & big), big);
}

TEST(FeatureRichCropTest, GrayscaleInputKeepsWholeImage) {
  cv::Mat gray(100, 120, CV_8UC1);
  cv::randu(gray, 0, 255);
  const CropResult r = SelectFeatureRichCrop(gray, CropOptions());
  EXPECT_TRUE(r.whole_image);
  EXPECT_EQ(r.roi, cv::Rect(0, 0, 120, 100));
  EXPECT_GT(r.fast_keypoints, 0);
}

TEST(FeatureRichCropTest, InvalidOptionsThrow) {
  CropOptions options;
  options.percentile = 100;
  EXPECT_THROW(SelectFeatureRichCrop(cv::Mat(10, 10, CV_8UC3), options), InvalidArgument);
}

}  // namespace
}  // namespace placedb
