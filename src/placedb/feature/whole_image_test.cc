#include "placedb/feature/whole_image.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <vector>

#include "placedb/feature/extractor.h"
#include "placedb/feature/testing.h"
#include "placedb/util/error.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
using testing_util::RtabmapImage;

double Similarity(const cv::Mat& a, const cv::Mat& b) {
  EXPECT_EQ(a.cols, b.cols);
  return WholeImageSimilarity(a.ptr<int8_t>(), b.ptr<int8_t>(), a.cols);
}

TEST(WholeImageTest, DescriptorShapeAndValues) {
  const cv::Mat image = cv::imread(RtabmapImage(1));
  ASSERT_FALSE(image.empty());
  const WholeImageOptions o;
  const cv::Mat d = ComputeWholeImageDescriptor(image, o);
  EXPECT_EQ(d.rows, 1);
  EXPECT_EQ(d.cols, 32 * 24);
  EXPECT_EQ(d.type(), CV_8S);
  int nonzero = 0;
  for (int i = 0; i < d.cols; ++i) {
    EXPECT_GE(d.at<int8_t>(i), -127);
    nonzero += d.at<int8_t>(i) != 0;
  }
  EXPECT_GT(nonzero, d.cols / 2);
  // Deterministic; grey and BGR inputs agree (the same grey image).
  EXPECT_EQ(cv::norm(d, ComputeWholeImageDescriptor(image, o), cv::NORM_L1), 0.0);
  cv::Mat gray;
  cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(cv::norm(d, ComputeWholeImageDescriptor(gray, o), cv::NORM_L1), 0.0);
  EXPECT_NEAR(Similarity(d, d), 1.0, 1e-12);
  // Each full tile has mean near 0 (the normalisation).
  for (int ty = 0; ty < 24; ty += 8) {
    for (int tx = 0; tx < 32; tx += 8) {
      double sum = 0;
      for (int y = ty; y < ty + 8; ++y)
        for (int x = tx; x < tx + 8; ++x) sum += d.at<int8_t>(y * 32 + x);
      EXPECT_LT(std::abs(sum / 64), 6.0) << tx << "," << ty;
    }
  }
  // Other sizes, tiles at the edges smaller than a patch.
  WholeImageOptions odd;
  odd.width = 13;
  odd.height = 7;
  odd.patch = 5;
  const cv::Mat e = ComputeWholeImageDescriptor(image, odd);
  EXPECT_EQ(e.cols, 13 * 7);
  // The corner tile is one pixel (13 = 2 * 6 + 1, 7 = 6 + 1): flat, zero.
  odd.patch = 6;
  const cv::Mat f = ComputeWholeImageDescriptor(image, odd);
  EXPECT_EQ(f.at<int8_t>(6 * 13 + 12), 0);
  EXPECT_NE(cv::countNonZero(f.colRange(0, 12)), 0);
}

TEST(WholeImageTest, FlatEmptyAndBadImages) {
  const WholeImageOptions o;
  const cv::Mat flat(120, 160, CV_8UC3, cv::Scalar(90, 90, 90));
  const cv::Mat d = ComputeWholeImageDescriptor(flat, o);
  EXPECT_EQ(cv::countNonZero(d), 0);
  EXPECT_EQ(Similarity(d, d), 0.0);  // a zero norm
  EXPECT_THROW(ComputeWholeImageDescriptor(cv::Mat(), o), InvalidArgument);
  EXPECT_THROW(ComputeWholeImageDescriptor(cv::Mat(10, 10, CV_32F, cv::Scalar(1)), o),
               InvalidArgument);
  WholeImageOptions bad;
  bad.patch = 30;  // > min(32, 24)
  EXPECT_NE(bad.Check().find("`whole_image_patch`"), std::string::npos) << bad.Check();
  EXPECT_THROW(ComputeWholeImageDescriptor(flat, bad), InvalidArgument);
  // A tiny image is upscaled by the resize; it never fails.
  const cv::Mat tiny(1, 1, CV_8UC1, cv::Scalar(7));
  EXPECT_EQ(ComputeWholeImageDescriptor(tiny, o).cols, 32 * 24);
}

// Brightness and contrast changes leave the descriptor nearly unchanged;
// another place of the loop is far less similar.
TEST(WholeImageTest, InvariantToBrightnessAndContrast) {
  const WholeImageOptions o;
  const cv::Mat image = cv::imread(RtabmapImage(1));
  const cv::Mat d = ComputeWholeImageDescriptor(image, o);
  for (const auto& [alpha, beta] : std::vector<std::pair<double, double>>{
           {1.0, 40.0}, {1.0, -40.0}, {0.6, 10.0}, {1.3, -20.0}, {0.5, 60.0}}) {
    cv::Mat changed;
    image.convertTo(changed, -1, alpha, beta);
    const double s = Similarity(d, ComputeWholeImageDescriptor(changed, o));
    EXPECT_GT(s, 0.95) << "alpha " << alpha << " beta " << beta;
  }
  const double other = Similarity(d, ComputeWholeImageDescriptor(cv::imread(RtabmapImage(20)), o));
  EXPECT_LT(other, 0.8);
  // A neighbouring frame is closer than a distant one.
  const double next = Similarity(d, ComputeWholeImageDescriptor(cv::imread(RtabmapImage(2)), o));
  EXPECT_GT(next, other);
  // Cosine range and symmetry.
  cv::Mat negated = -d;
  EXPECT_NEAR(Similarity(d, negated), -1.0, 1e-12);
}

std::vector<int8_t> RandomRows(size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<int8_t> v(n);
  for (int8_t& x : v) x = static_cast<int8_t>(static_cast<int>(rng() % 255) - 127);
  return v;
}

TEST(WholeImageTest, KernelsEqualTheReference) {
  for (const int dims : {1, 7, 31, 32, 33, 63, 95, 768, 769, 4096}) {
    const size_t count = 37;  // groups of four rows and one left over
    const std::vector<int8_t> q = RandomRows(dims, dims);
    std::vector<int8_t> rows = RandomRows(count * dims, dims + 1000);
    // Extremes, a zero row and the query itself among them.
    std::fill(rows.begin(), rows.begin() + dims, int8_t{0});
    std::fill(rows.begin() + dims, rows.begin() + 2 * dims, int8_t{127});
    std::fill(rows.begin() + 2 * dims, rows.begin() + 3 * dims, int8_t{-127});
    std::copy(q.begin(), q.end(), rows.begin() + 3 * dims);
    std::vector<float> ref(count), got(count);
    WholeImageSimilaritiesWith(WholeImageKernel::kReference, q.data(), rows.data(), count, dims,
                               ref.data());
    for (size_t i = 0; i < count; ++i) {
      EXPECT_FLOAT_EQ(ref[i],
                      static_cast<float>(WholeImageSimilarity(q.data(), rows.data() + i * dims,
                                                              dims)))
          << dims << " " << i;
      EXPECT_GE(ref[i], -1.0f);
      EXPECT_LE(ref[i], 1.0f);
    }
    EXPECT_EQ(ref[0], 0.0f);
    EXPECT_NEAR(ref[3], 1.0f, 1e-6);
    for (int k = 0; k < kNumWholeImageKernels; ++k) {
      const auto kernel = static_cast<WholeImageKernel>(k);
      if (!WholeImageKernelAvailable(kernel)) continue;
      // Unaligned rows too.
      std::vector<int8_t> shifted(rows.size() + 1);
      std::copy(rows.begin(), rows.end(), shifted.begin() + 1);
      WholeImageSimilaritiesWith(kernel, q.data(), shifted.data() + 1, count, dims, got.data());
      for (size_t i = 0; i < count; ++i)
        EXPECT_EQ(got[i], ref[i]) << WholeImageKernelName(kernel) << " dims " << dims << " " << i;
      // A zero query: every cosine 0.
      const std::vector<int8_t> zero(static_cast<size_t>(dims), 0);
      WholeImageSimilaritiesWith(kernel, zero.data(), rows.data(), count, dims, got.data());
      for (size_t i = 0; i < count; ++i) EXPECT_EQ(got[i], 0.0f) << WholeImageKernelName(kernel);
      if (testing_util::DirtyUpperStateKnown()) {
        EXPECT_FALSE(testing_util::DirtyUpperState()) << WholeImageKernelName(kernel);
      }
    }
    WholeImageSimilarities(q.data(), rows.data(), count, dims, got.data());
    EXPECT_EQ(got, ref);
  }
  EXPECT_THROW(WholeImageSimilaritiesWith(WholeImageKernel::kReference, nullptr, nullptr, 0, 0,
                                          nullptr),
               InvalidArgument);
}

// The extractor fills FeatureSet::whole_image from the image as given (not
// the upscaled one), and leaves it empty when the channel is off.
TEST(WholeImageTest, ExtractorFillsIt) {
  const cv::Mat image = cv::imread(RtabmapImage(5));
  cv::Mat small;
  cv::resize(image, small, cv::Size(160, 120), 0, 0, cv::INTER_AREA);
  ExtractorOptions o = testing::ModelFreeExtractorOptions();
  for (const cv::Mat& m : {image, small}) {
    const FeatureSet set = FeatureExtractor::Create(o)->Extract(m);
    ASSERT_EQ(set.whole_image.cols, 768);
    EXPECT_EQ(cv::norm(set.whole_image, ComputeWholeImageDescriptor(m, o.whole_image),
                       cv::NORM_L1),
              0.0);
  }
  EXPECT_TRUE(FeatureExtractor::Create(o)->Extract(cv::Mat()).whole_image.empty());
  o.whole_image.enabled = false;
  EXPECT_TRUE(FeatureExtractor::Create(o)->Extract(image).whole_image.empty());
  o.type = FeatureType::kSurf;
  o.whole_image.enabled = true;
  o.whole_image.width = 16;
  o.whole_image.height = 12;
  o.whole_image.patch = 4;
  EXPECT_EQ(FeatureExtractor::Create(o)->Extract(small).whole_image.cols, 192);
}

}  // namespace
}  // namespace placedb
