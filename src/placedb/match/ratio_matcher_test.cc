#include "placedb/match/ratio_matcher.h"

#include <gtest/gtest.h>

#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "placedb/feature/extractor.h"

namespace placedb {
namespace {

FeatureSet Orb(const std::string& path) {
  const cv::Mat img = cv::imread(path);
  EXPECT_FALSE(img.empty()) << path;
  return FeatureExtractor::Create(ExtractorOptions())->Extract(img);
}

// Our matcher counts exactly what OpenCV's BFMatcher + ratio test counts (the
// paper's method), on real descriptors.
TEST(RatioMatcherTest, EqualsBfMatcherRatioTestOnRealImages) {
  const FeatureSet a = Orb(PLACEDB_DATA_DIR "/rtabmap_loop/images/042.jpg");
  const FeatureSet b = Orb(PLACEDB_DATA_DIR "/rtabmap_loop/images/002.jpg");
  const FeatureSet c = Orb(PLACEDB_DATA_DIR "/rtabmap_loop/images/020.jpg");
  MatchOptions options;
  cv::BFMatcher bf(cv::NORM_HAMMING);
  for (const FeatureSet* db : {&b, &c}) {
    std::vector<std::vector<cv::DMatch>> knn;
    bf.knnMatch(a.descriptors, db->descriptors, knn, 2);
    int expected = 0;
    for (const auto& m : knn) {
      if (m.size() == 2 && m[0].distance < options.ratio * m[1].distance) ++expected;
    }
    std::vector<cv::DMatch> matches;
    const int got = CountRatioMatches(MakeDescriptorBlock(a, nullptr),
                                      MakeDescriptorBlock(*db, nullptr), options, &matches);
    EXPECT_EQ(got, expected);
    EXPECT_EQ(static_cast<int>(matches.size()), got);
  }
  // The revisit (42 sees the place of 2) has far more matches than an
  // unrelated place (20).
  const int same =
      CountRatioMatches(MakeDescriptorBlock(a, nullptr), MakeDescriptorBlock(b, nullptr), options);
  const int other =
      CountRatioMatches(MakeDescriptorBlock(a, nullptr), MakeDescriptorBlock(c, nullptr), options);
  EXPECT_GT(same, 3 * other) << same << " vs " << other;
}

TEST(RatioMatcherTest, MixingFeatureTypesThrows) {
  FeatureSet orb;
  orb.type = FeatureType::kOrb;
  orb.descriptors = cv::Mat(2, 32, CV_8U, cv::Scalar(0));
  orb.keypoints.resize(2);
  FeatureSet surf;
  surf.type = FeatureType::kSurf;
  surf.descriptors = cv::Mat(2, 64, CV_32F, cv::Scalar(0));
  surf.keypoints.resize(2);
  EXPECT_THROW(CountRatioMatches(MakeDescriptorBlock(orb, nullptr),
                                 MakeDescriptorBlock(surf, nullptr), MatchOptions()),
               std::invalid_argument);
}

TEST(RatioMatcherTest, SurfLaplacianSignRejects) {
  // Two identical float descriptors with opposite Laplacian signs never match.
  FeatureSet q, d;
  q.type = d.type = FeatureType::kSurf;
  q.descriptors = cv::Mat(1, 64, CV_32F, cv::Scalar(0.125f));
  d.descriptors = cv::Mat(2, 64, CV_32F, cv::Scalar(0.125f));
  d.descriptors.at<float>(1, 0) = 0.9f;
  q.keypoints.resize(1);
  d.keypoints.resize(2);
  q.keypoints[0].class_id = 1;
  d.keypoints[0].class_id = -1;
  d.keypoints[1].class_id = 1;
  std::vector<int8_t> lq, ld;
  std::vector<cv::DMatch> matches;
  MatchOptions options;
  options.max_l2 = 0;  // the same-sign descriptor is far: no distance limit here
  EXPECT_EQ(CountRatioMatches(MakeDescriptorBlock(q, &lq), MakeDescriptorBlock(d, &ld), options,
                              &matches),
            1);
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].trainIdx, 1);  // the same-sign one, though farther
  options.use_laplacian_sign = false;
  matches.clear();
  CountRatioMatches(MakeDescriptorBlock(q, &lq), MakeDescriptorBlock(d, &ld), options, &matches);
  // Without the sign the exact copy is nearest (ratio 0 < 0.8 x d2).
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].trainIdx, 0);
}

TEST(RatioMatcherTest, DistanceLimitsRejectFarMatches) {
  const FeatureSet a = Orb(PLACEDB_DATA_DIR "/rtabmap_loop/images/042.jpg");
  const FeatureSet b = Orb(PLACEDB_DATA_DIR "/rtabmap_loop/images/002.jpg");
  MatchOptions loose;
  loose.max_hamming = 0;
  MatchOptions strict;
  strict.max_hamming = 30;
  std::vector<cv::DMatch> matches;
  const int all = CountRatioMatches(MakeDescriptorBlock(a, nullptr),
                                    MakeDescriptorBlock(b, nullptr), loose, &matches);
  int within = 0;
  for (const auto& m : matches) within += m.distance <= 30;
  const int limited =
      CountRatioMatches(MakeDescriptorBlock(a, nullptr), MakeDescriptorBlock(b, nullptr), strict);
  EXPECT_EQ(limited, within);
  EXPECT_LT(limited, all);
  EXPECT_GT(limited, 0);
}

TEST(RatioMatcherTest, EmptyInputs) {
  FeatureSet empty;
  empty.descriptors = cv::Mat(0, 32, CV_8U);
  const FeatureSet a = Orb(PLACEDB_DATA_DIR "/rtabmap_loop/images/001.jpg");
  EXPECT_EQ(CountRatioMatches(MakeDescriptorBlock(empty, nullptr), MakeDescriptorBlock(a, nullptr),
                              MatchOptions()),
            0);
  EXPECT_EQ(CountRatioMatches(MakeDescriptorBlock(a, nullptr), MakeDescriptorBlock(empty, nullptr),
                              MatchOptions()),
            0);
  MatchOptions bad;
  bad.ratio = 0;
  EXPECT_NE(bad.Check(), "");
}

}  // namespace
}  // namespace placedb
