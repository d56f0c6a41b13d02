#include "placedb/match/geometric_verification.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <thread>
#include <vector>

#include "placedb/feature/extractor.h"
#include "placedb/feature/testing.h"
#include "placedb/match/ratio_matcher.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {

using testing_util::ThrowsWith;

constexpr int kWidth = 640;
constexpr int kHeight = 480;

// Point pairs and which of them follow the true geometry.
struct Pairs {
  std::vector<cv::Point2f> query, keyframe;
  std::vector<bool> is_inlier;
  int NumInliers() const {
    int n = 0;
    for (bool b : is_inlier) n += b;
    return n;
  }
};

cv::Point2f RandomPoint(cv::RNG& rng) {
  return cv::Point2f(rng.uniform(0.f, static_cast<float>(kWidth)),
                     rng.uniform(0.f, static_cast<float>(kHeight)));
}

cv::Point2f Apply(const cv::Matx33d& h, const cv::Point2f& p) {
  const cv::Vec3d v = h * cv::Vec3d(p.x, p.y, 1.0);
  return cv::Point2f(static_cast<float>(v[0] / v[2]), static_cast<float>(v[1] / v[2]));
}

const cv::Matx33d kHomography(0.9, 0.08, 25.0,    //
                              -0.06, 1.05, 12.0,  //
                              1e-4, -5e-5, 1.0);

// `n` pairs, a fraction `inlier_fraction` of them related by kHomography
// plus Gaussian noise (sigma 0.5 px), the rest random.
Pairs HomographyPairs(int n, double inlier_fraction, uint64_t seed) {
  cv::RNG rng(seed);
  Pairs pairs;
  for (int i = 0; i < n; ++i) {
    const cv::Point2f p = RandomPoint(rng);
    const bool inlier = i < static_cast<int>(std::lround(n * inlier_fraction));
    cv::Point2f q;
    if (inlier) {
      q = Apply(kHomography, p) +
          cv::Point2f(static_cast<float>(rng.gaussian(0.5)), static_cast<float>(rng.gaussian(0.5)));
    } else {
      q = RandomPoint(rng);
    }
    pairs.query.push_back(p);
    pairs.keyframe.push_back(q);
    pairs.is_inlier.push_back(inlier);
  }
  return pairs;
}

// `num_inliers` 3-D points seen by two pinhole cameras (f = 500, c = (320,
// 240); the second rotated by a few degrees and moved sideways), with
// Gaussian noise (sigma 0.3 px), followed by `num_outliers` random pairs.
Pairs TwoViewPairs(int num_inliers, int num_outliers, uint64_t seed) {
  cv::RNG rng(seed);
  const cv::Matx33d k(500, 0, 320, 0, 500, 240, 0, 0, 1);
  cv::Matx33d r;
  cv::Rodrigues(cv::Vec3d(0.03, -0.06, 0.02), r);
  const cv::Vec3d t(-0.6, 0.05, 0.1);
  Pairs pairs;
  while (static_cast<int>(pairs.query.size()) < num_inliers) {
    const cv::Vec3d x(rng.uniform(-3.0, 3.0), rng.uniform(-2.0, 2.0), rng.uniform(4.0, 12.0));
    const cv::Vec3d a = k * x;
    const cv::Vec3d b = k * (r * x + t);
    const cv::Point2f pa(static_cast<float>(a[0] / a[2] + rng.gaussian(0.3)),
                         static_cast<float>(a[1] / a[2] + rng.gaussian(0.3)));
    const cv::Point2f pb(static_cast<float>(b[0] / b[2] + rng.gaussian(0.3)),
                         static_cast<float>(b[1] / b[2] + rng.gaussian(0.3)));
    const cv::Rect2f image(0, 0, kWidth, kHeight);
    if (!image.contains(pa) || !image.contains(pb)) continue;  // both cameras see it
    pairs.query.push_back(pa);
    pairs.keyframe.push_back(pb);
    pairs.is_inlier.push_back(true);
  }
  for (int i = 0; i < num_outliers; ++i) {
    pairs.query.push_back(RandomPoint(rng));
    pairs.keyframe.push_back(RandomPoint(rng));
    pairs.is_inlier.push_back(false);
  }
  return pairs;
}

// How many pairs the mask marks as inliers among the true inliers and among
// the true outliers.
struct Confusion {
  int true_marked = 0;
  int false_marked = 0;
};
Confusion Compare(const VerifyResult& result, const Pairs& pairs) {
  Confusion c;
  for (size_t i = 0; i < result.inlier_mask.size(); ++i) {
    if (result.inlier_mask[i] == 0) continue;
    if (pairs.is_inlier[i]) {
      ++c.true_marked;
    } else {
      ++c.false_marked;
    }
  }
  return c;
}

int CountMask(const std::vector<uint8_t>& mask) {
  int n = 0;
  for (uint8_t m : mask) n += m != 0;
  return n;
}

VerifyOptions WithModel(GeometricModel model) {
  VerifyOptions options;
  options.model = model;
  return options;
}

// Homography model on 70 exact (+0.5 px noise) and 30 random pairs: finds
// (nearly) all true inliers, few false ones, one mask entry per pair, and a
// matrix that maps points like the true one.
TEST(GeometricVerificationTest, HomographyFindsPlantedInliers) {
  const Pairs pairs = HomographyPairs(100, 0.7, 1);
  const VerifyResult result =
      VerifyMatches(pairs.query, pairs.keyframe, WithModel(GeometricModel::kHomography));
  ASSERT_TRUE(result.estimated);
  ASSERT_EQ(result.inlier_mask.size(), pairs.query.size());
  EXPECT_EQ(result.num_inliers, CountMask(result.inlier_mask));
  const Confusion c = Compare(result, pairs);
  std::printf("homography: %d inliers (%d of %d true, %d false)\n", result.num_inliers,
              c.true_marked, pairs.NumInliers(), c.false_marked);
  EXPECT_GE(result.num_inliers, 65);
  EXPECT_GE(c.true_marked, 65);
  EXPECT_LE(c.false_marked, 2);
  ASSERT_EQ(result.model.rows, 3);
  ASSERT_EQ(result.model.cols, 3);
  ASSERT_EQ(result.model.type(), CV_64F);
  const cv::Matx33d h(result.model);
  for (const cv::Point2f& p :
       {cv::Point2f(0, 0), cv::Point2f(320, 240), cv::Point2f(600, 50), cv::Point2f(40, 460)}) {
    EXPECT_LT(cv::norm(Apply(h, p) - Apply(kHomography, p)), 1.5) << p;
  }
}

// Fundamental-matrix model on two pinhole views of 100 3-D points plus 40
// random pairs: at least 90% of the true inliers, at most a few false ones,
// and the true pairs satisfy the epipolar constraint of the estimate.
TEST(GeometricVerificationTest, FundamentalFindsPlantedInliers) {
  const Pairs pairs = TwoViewPairs(100, 40, 1);
  const VerifyResult result = VerifyMatches(pairs.query, pairs.keyframe, VerifyOptions());
  ASSERT_TRUE(result.estimated);
  ASSERT_EQ(result.inlier_mask.size(), pairs.query.size());
  EXPECT_EQ(result.num_inliers, CountMask(result.inlier_mask));
  const Confusion c = Compare(result, pairs);
  const int truth = pairs.NumInliers();
  std::printf("fundamental: %d inliers (%d of %d true, %d false)\n", result.num_inliers,
              c.true_marked, truth, c.false_marked);
  EXPECT_GE(result.num_inliers, (truth * 9 + 9) / 10);
  EXPECT_GE(c.true_marked, (truth * 9 + 9) / 10);
  EXPECT_LE(result.num_inliers, truth + 4);
  // Distance of the keyframe point from the query point's epipolar line.
  const cv::Matx33d f(result.model);
  double worst = 0;
  for (int i = 0; i < truth; ++i) {
    const cv::Vec3d line = f * cv::Vec3d(pairs.query[i].x, pairs.query[i].y, 1);
    const double d = std::abs(line.dot(cv::Vec3d(pairs.keyframe[i].x, pairs.keyframe[i].y, 1))) /
                     std::hypot(line[0], line[1]);
    worst = std::max(worst, d);
  }
  std::printf("fundamental: worst epipolar distance of a true pair %.2f px\n", worst);
  EXPECT_LT(worst, 5.0);
}

// Random pairs have no geometry: the homography model keeps only a handful of
// them (far fewer than the planted inliers above). The fundamental matrix,
// whose inlier band crosses the whole image, keeps more; its count is shown.
TEST(GeometricVerificationTest, RandomPairsGiveFewInliers) {
  const Pairs pairs = HomographyPairs(200, 0.0, 1);
  const VerifyResult h =
      VerifyMatches(pairs.query, pairs.keyframe, WithModel(GeometricModel::kHomography));
  const VerifyResult f = VerifyMatches(pairs.query, pairs.keyframe, VerifyOptions());
  std::printf("random pairs (200): homography %d inliers, fundamental %d inliers\n", h.num_inliers,
              f.num_inliers);
  EXPECT_LT(h.num_inliers, 200 / 5);
  EXPECT_LT(h.num_inliers, 65 / 3);
  EXPECT_LT(f.num_inliers, 200 / 4);
}

// The same input and seed give the same mask every time, serially and from
// two threads at once (the estimator keeps no shared state).
TEST(GeometricVerificationTest, DeterministicAndThreadSafe) {
  const Pairs pairs = TwoViewPairs(80, 80, 3);
  for (const GeometricModel model : {GeometricModel::kFundamental, GeometricModel::kHomography}) {
    SCOPED_TRACE(GeometricModelName(model));
    const VerifyOptions options = WithModel(model);
    const VerifyResult first = VerifyMatches(pairs.query, pairs.keyframe, options);
    const VerifyResult second = VerifyMatches(pairs.query, pairs.keyframe, options);
    ASSERT_TRUE(first.estimated);
    EXPECT_EQ(first.inlier_mask, second.inlier_mask);
    EXPECT_EQ(first.num_inliers, second.num_inliers);
    EXPECT_EQ(cv::norm(first.model, second.model, cv::NORM_INF), 0.0);

    std::vector<VerifyResult> parallel(2);
    std::vector<std::thread> threads;
    for (int t = 0; t < 2; ++t) {
      threads.emplace_back([&, t] {
        // Several runs per thread so that they overlap.
        for (int run = 0; run < 5; ++run) {
          parallel[t] = VerifyMatches(pairs.query, pairs.keyframe, options);
        }
      });
    }
    for (std::thread& t : threads) t.join();
    for (const VerifyResult& r : parallel) {
      EXPECT_EQ(r.inlier_mask, first.inlier_mask);
      EXPECT_EQ(r.num_inliers, first.num_inliers);
    }
  }
}

// Fewer pairs than a model needs: nothing estimated, 0 inliers, empty mask.
TEST(GeometricVerificationTest, TooFewPairsGiveNoInliers) {
  EXPECT_EQ(MinimumMatches(GeometricModel::kFundamental), 8);
  EXPECT_EQ(MinimumMatches(GeometricModel::kHomography), 4);
  const Pairs pairs = HomographyPairs(20, 1.0, 5);
  for (const GeometricModel model : {GeometricModel::kFundamental, GeometricModel::kHomography}) {
    SCOPED_TRACE(GeometricModelName(model));
    const int n = MinimumMatches(model) - 1;
    const std::vector<cv::Point2f> q(pairs.query.begin(), pairs.query.begin() + n);
    const std::vector<cv::Point2f> k(pairs.keyframe.begin(), pairs.keyframe.begin() + n);
    const VerifyResult result = VerifyMatches(q, k, WithModel(model));
    EXPECT_FALSE(result.estimated);
    EXPECT_EQ(result.num_inliers, 0);
    EXPECT_TRUE(result.inlier_mask.empty());
    EXPECT_TRUE(result.model.empty());
    const VerifyResult none = VerifyMatches({}, {}, WithModel(model));
    EXPECT_FALSE(none.estimated);
    EXPECT_EQ(none.num_inliers, 0);
  }
  // Exactly the minimum of exact homography pairs is enough.
  const std::vector<cv::Point2f> q(pairs.query.begin(), pairs.query.begin() + 4);
  const std::vector<cv::Point2f> k(pairs.keyframe.begin(), pairs.keyframe.begin() + 4);
  const VerifyResult four = VerifyMatches(q, k, WithModel(GeometricModel::kHomography));
  EXPECT_TRUE(four.estimated);
  EXPECT_EQ(four.num_inliers, 4);
}

// Invalid input is the caller's error: lists of different sizes, non-finite
// coordinates (on either side), invalid options.
TEST(GeometricVerificationTest, InvalidInputThrows) {
  Pairs pairs = HomographyPairs(20, 1.0, 6);
  std::vector<cv::Point2f> shorter = pairs.keyframe;
  shorter.pop_back();
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { VerifyMatches(pairs.query, shorter, VerifyOptions()); },
      {"one keyframe point per query point", "20 query points", "19 keyframe points"}));
  std::vector<cv::Point2f> nan = pairs.query;
  nan[7].y = std::numeric_limits<float>::quiet_NaN();
  EXPECT_TRUE(
      ThrowsWith<InvalidArgument>([&] { VerifyMatches(nan, pairs.keyframe, VerifyOptions()); },
                                  {"point pair 7", "not finite"}));
  std::vector<cv::Point2f> inf = pairs.keyframe;
  inf[3].x = std::numeric_limits<float>::infinity();
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { VerifyMatches(pairs.query, inf, WithModel(GeometricModel::kHomography)); },
      {"point pair 3", "not finite"}));
  // Checked even when there are too few pairs to estimate anything.
  const std::vector<cv::Point2f> one_nan = {cv::Point2f(std::nanf(""), 0)};
  EXPECT_THROW(VerifyMatches(one_nan, {cv::Point2f(0, 0)}, VerifyOptions()), InvalidArgument);
  VerifyOptions bad;
  bad.max_error_px = 0;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { VerifyMatches(pairs.query, pairs.keyframe, bad); },
                                          {"verify_error"}));
}

// Degenerate input (all points identical; all points on one line) does not
// crash; whatever comes back is consistent.
TEST(GeometricVerificationTest, DegenerateInputDoesNotCrash) {
  std::vector<cv::Point2f> same(30, cv::Point2f(100, 100));
  std::vector<cv::Point2f> line_q, line_k;
  for (int i = 0; i < 30; ++i) {
    line_q.emplace_back(10.f + 20.f * i, 50.f + 10.f * i);
    line_k.emplace_back(15.f + 18.f * i, 40.f + 12.f * i);
  }
  for (const GeometricModel model : {GeometricModel::kFundamental, GeometricModel::kHomography}) {
    SCOPED_TRACE(GeometricModelName(model));
    for (const bool identical : {true, false}) {
      const std::vector<cv::Point2f>& q = identical ? same : line_q;
      const std::vector<cv::Point2f>& k = identical ? same : line_k;
      VerifyResult result;
      ASSERT_NO_THROW(result = VerifyMatches(q, k, WithModel(model)));
      std::printf("degenerate (%s, %s): estimated %d, %d inliers\n", GeometricModelName(model),
                  identical ? "identical" : "collinear", result.estimated, result.num_inliers);
      if (result.estimated) {
        EXPECT_EQ(result.inlier_mask.size(), q.size());
        EXPECT_EQ(result.num_inliers, CountMask(result.inlier_mask));
        EXPECT_EQ(result.model.rows, 3);
      } else {
        EXPECT_EQ(result.num_inliers, 0);
        EXPECT_TRUE(result.inlier_mask.empty());
      }
    }
  }
}

// Check() enforces every documented range and names the field.
TEST(GeometricVerificationTest, OptionsCheckRangesAndModelNames) {
  EXPECT_EQ(VerifyOptions().Check(), "");
  const auto with = [](auto set) {
    VerifyOptions o;
    set(o);
    return o.Check();
  };
  const auto starts = [](const std::string& reason, const std::string& prefix) {
    return reason.rfind(prefix, 0) == 0;
  };
  EXPECT_EQ(with([](VerifyOptions& o) { o.num_candidates = 0; }),
            "`verify_candidates` must be in [1, 1000] (got 0)");
  EXPECT_EQ(with([](VerifyOptions& o) { o.num_candidates = 1001; }),
            "`verify_candidates` must be in [1, 1000] (got 1001)");
  EXPECT_EQ(with([](VerifyOptions& o) { o.num_candidates = 1000; }), "");
  EXPECT_EQ(with([](VerifyOptions& o) { o.max_error_px = 0; }),
            "`verify_error` must be in (0, 100] (got 0)");
  EXPECT_TRUE(starts(
      with([](VerifyOptions& o) { o.max_error_px = std::numeric_limits<double>::quiet_NaN(); }),
      "`verify_error` must be in (0, 100]"));
  EXPECT_EQ(with([](VerifyOptions& o) { o.max_error_px = 101; }),
            "`verify_error` must be in (0, 100] (got 101)");
  EXPECT_EQ(with([](VerifyOptions& o) { o.max_error_px = 100; }), "");
  EXPECT_TRUE(starts(with([](VerifyOptions& o) { o.confidence = 1.0; }), "`verify_confidence` must be in"));
  EXPECT_TRUE(starts(with([](VerifyOptions& o) { o.confidence = 0.4; }), "`verify_confidence` must be in"));
  EXPECT_EQ(with([](VerifyOptions& o) { o.confidence = 0.5; }), "");
  EXPECT_EQ(with([](VerifyOptions& o) { o.max_iterations = 0; }),
            "`verify_iterations` must be in [1, 100000] (got 0)");
  EXPECT_TRUE(starts(with([](VerifyOptions& o) { o.max_iterations = 100001; }),
                     "`verify_iterations` must be in"));
  EXPECT_TRUE(starts(with([](VerifyOptions& o) { o.seed = -1; }), "`verify_seed` must be in [0, "));
  EXPECT_EQ(with([](VerifyOptions& o) { o.seed = std::numeric_limits<int>::max(); }), "");

  EXPECT_EQ(ParseGeometricModel("fundamental"), GeometricModel::kFundamental);
  EXPECT_EQ(ParseGeometricModel("homography"), GeometricModel::kHomography);
  for (const GeometricModel model : {GeometricModel::kFundamental, GeometricModel::kHomography}) {
    EXPECT_EQ(ParseGeometricModel(GeometricModelName(model)), model);
  }
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([] { ParseGeometricModel("affine"); },
                                          {"unknown geometric model 'affine'"}));
  EXPECT_THROW(ParseGeometricModel(""), InvalidArgument);
}

FeatureSet Orb(const std::string& path) {
  const cv::Mat img = cv::imread(path);
  EXPECT_FALSE(img.empty()) << path;
  return FeatureExtractor::Create(testing::ModelFreeExtractorOptions())->Extract(img);
}

// The matched point pairs of query `a` and keyframe `b`.
void MatchedPoints(const FeatureSet& a, const FeatureSet& b, const MatchOptions& match_options,
                   std::vector<cv::Point2f>* pa, std::vector<cv::Point2f>* pb) {
  std::vector<cv::DMatch> matches;
  MatchDescriptors(MakeDescriptorBlock(a, nullptr), MakeDescriptorBlock(b, nullptr), match_options,
                   &matches);
  for (const cv::DMatch& m : matches) {
    pa->push_back(a.keypoints[m.queryIdx].pt);
    pb->push_back(b.keypoints[m.trainIdx].pt);
  }
}

// The plain ratio rule without a Hamming limit: many chance matches between
// unrelated images, for the verifier to reject.
MatchOptions Loose() {
  MatchOptions options;
  options.one_to_one = false;
  options.cross_check = false;
  options.max_hamming = 0;
  options.ratio = 1.0;
  return options;
}

// Real images: the Oxford graffiti pair (a plane seen from two viewpoints)
// verifies with a solid homography whose inliers all agree with the
// ground-truth homography H1to3p; graf1 against an unrelated indoor image
// verifies far fewer, with the default matching (measured: 32 inliers of 38
// matches vs 0 of 1) and with a loose matching that lets chance matches
// through (ratio 1, no Hamming limit, no guard; measured: 158 of 461 vs 31 of
// 451).
TEST(GeometricVerificationTest, RealImagesGrafPairVersusUnrelated) {
  const FeatureSet g1 = Orb(PLACEDB_DATA_DIR "/oxford_graf/graf1.png");
  const FeatureSet g3 = Orb(PLACEDB_DATA_DIR "/oxford_graf/graf3.png");
  const FeatureSet unrelated = Orb(testing_util::RtabmapImage(42));
  cv::FileStorage fs(PLACEDB_DATA_DIR "/oxford_graf/H1to3p.xml", cv::FileStorage::READ);
  ASSERT_TRUE(fs.isOpened());
  cv::Mat truth_mat;
  fs["H13"] >> truth_mat;
  ASSERT_EQ(truth_mat.size(), cv::Size(3, 3));
  const cv::Matx33d truth(truth_mat);
  const VerifyOptions options = WithModel(GeometricModel::kHomography);

  for (const bool loose : {false, true}) {
    SCOPED_TRACE(loose ? "loose matching" : "default matching");
    const MatchOptions match_options = loose ? Loose() : MatchOptions();
    std::vector<cv::Point2f> q, k;
    MatchedPoints(g1, g3, match_options, &q, &k);
    const VerifyResult same = VerifyMatches(q, k, options);
    int agree = 0;  // inliers within 5 px of where the ground truth puts them
    for (size_t i = 0; i < same.inlier_mask.size(); ++i) {
      if (same.inlier_mask[i] != 0 && cv::norm(Apply(truth, q[i]) - k[i]) < 5.0) ++agree;
    }
    std::vector<cv::Point2f> uq, uk;
    MatchedPoints(g1, unrelated, match_options, &uq, &uk);
    const VerifyResult other = VerifyMatches(uq, uk, options);
    const VerifyResult same_f = VerifyMatches(q, k, VerifyOptions());
    const VerifyResult other_f = VerifyMatches(uq, uk, VerifyOptions());
    std::printf(
        "%s matching: graf1->graf3 %zu matches, homography %d inliers (%d agree with H1to3p), "
        "fundamental %d; graf1->rtabmap 042 %zu matches, homography %d, fundamental %d\n",
        loose ? "loose" : "default", q.size(), same.num_inliers, agree, same_f.num_inliers,
        uq.size(), other.num_inliers, other_f.num_inliers);
    ASSERT_TRUE(same.estimated);
    EXPECT_GE(same.num_inliers, loose ? 140 : 28);
    EXPECT_GE(agree, same.num_inliers - 2);
    EXPECT_LE(other.num_inliers, loose ? 45 : 4);
    EXPECT_GT(same.num_inliers, 4 * std::max(other.num_inliers, 1));
    if (loose) {
      // Chance matches: fewer than 10% survive the homography.
      EXPECT_GT(uq.size(), 400u);
      EXPECT_LT(other.num_inliers * 10, static_cast<int>(uq.size()));
    }
  }
}

// Box and the cluttered scene containing it (default matching): the
// object's matches verify with a homography that puts the box inside the
// scene; the box against an unrelated image verifies (almost) nothing.
// Measured: 17 inliers of 17 matches vs 0 of 4.
TEST(GeometricVerificationTest, RealImagesBoxInScene) {
  const FeatureSet box = Orb(PLACEDB_DATA_DIR "/oxford_graf/box.png");
  const FeatureSet scene = Orb(PLACEDB_DATA_DIR "/oxford_graf/box_in_scene.png");
  const FeatureSet unrelated = Orb(testing_util::RtabmapImage(42));
  const VerifyOptions options = WithModel(GeometricModel::kHomography);
  std::vector<cv::Point2f> q, k, uq, uk;
  MatchedPoints(box, scene, MatchOptions(), &q, &k);
  MatchedPoints(box, unrelated, MatchOptions(), &uq, &uk);
  const VerifyResult same = VerifyMatches(q, k, options);
  const VerifyResult other = VerifyMatches(uq, uk, options);
  std::printf("box->box_in_scene: %zu matches, %d inliers; box->rtabmap 042: %zu, %d\n", q.size(),
              same.num_inliers, uq.size(), other.num_inliers);
  ASSERT_TRUE(same.estimated);
  EXPECT_GE(same.num_inliers, 14);
  EXPECT_LE(other.num_inliers, 4);
  // The box (324x223) lands inside the 512x384 scene.
  const cv::Point2f center = Apply(cv::Matx33d(same.model), cv::Point2f(162, 111));
  EXPECT_TRUE(cv::Rect2f(0, 0, 512, 384).contains(center)) << center;
}

}  // namespace
}  // namespace placedb
