#include "placedb/match/ratio_matcher.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "placedb/feature/extractor.h"
#include "placedb/feature/testing.h"
#include "placedb/match/hamming.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {

using testing_util::ThrowsWith;

FeatureSet Orb(const std::string& path) {
  const cv::Mat img = cv::imread(path);
  EXPECT_FALSE(img.empty()) << path;
  return FeatureExtractor::Create(testing::ModelFreeExtractorOptions())->Extract(img);
}

std::string Image(int n) { return testing_util::RtabmapImage(n); }

// An ORB set of `rows` random descriptors (no keypoint positions needed).
FeatureSet RandomOrb(int rows, uint32_t seed) {
  std::mt19937 rng(seed);
  FeatureSet set;
  set.type = FeatureType::kOrb;
  set.descriptors = cv::Mat(rows, 32, CV_8U);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < 32; ++c) set.descriptors.at<uint8_t>(r, c) = rng() & 0xff;
  }
  set.keypoints.resize(rows);
  return set;
}

// The first `rows` features of `set`.
FeatureSet FirstRows(const FeatureSet& set, int rows) {
  FeatureSet out;
  out.type = set.type;
  out.keypoints.assign(set.keypoints.begin(), set.keypoints.begin() + rows);
  out.descriptors = set.descriptors.rowRange(0, rows).clone();
  return out;
}

int Match(const FeatureSet& query, const FeatureSet& db, const MatchOptions& options,
          std::vector<cv::DMatch>* matches = nullptr) {
  return MatchDescriptors(MakeDescriptorBlock(query, nullptr), MakeDescriptorBlock(db, nullptr),
                          options, matches);
}

MatchOptions Plain() {
  MatchOptions options;
  options.one_to_one = false;
  options.cross_check = false;
  return options;
}

// With one_to_one and cross_check off, our matcher returns exactly what
// OpenCV's BFMatcher + Lowe's ratio test return (the paper's rule), match by
// match, with and without the absolute Hamming limit, on real descriptors.
TEST(RatioMatcherTest, PlainRuleEqualsBfMatcherRatioTestOnRealImages) {
  const FeatureSet a = Orb(Image(42));
  const FeatureSet b = Orb(Image(2));
  const FeatureSet c = Orb(Image(20));
  ASSERT_GT(a.size(), 100u);
  cv::BFMatcher bf(cv::NORM_HAMMING);
  for (const int max_hamming : {0, 64}) {
    MatchOptions options = Plain();
    options.max_hamming = max_hamming;
    for (const FeatureSet* db : {&b, &c}) {
      std::vector<std::vector<cv::DMatch>> knn;
      bf.knnMatch(a.descriptors, db->descriptors, knn, 2);
      std::vector<cv::DMatch> expected;
      for (const auto& m : knn) {
        if (m.size() == 2 && m[0].distance < options.ratio * m[1].distance &&
            (max_hamming == 0 || m[0].distance <= max_hamming)) {
          expected.push_back(m[0]);
        }
      }
      std::vector<cv::DMatch> matches;
      const int got = Match(a, *db, options, &matches);
      EXPECT_EQ(got, static_cast<int>(expected.size())) << "max_hamming " << max_hamming;
      ASSERT_EQ(matches.size(), expected.size());
      for (size_t i = 0; i < matches.size(); ++i) {
        // The ratio test leaves no tie for the nearest: trainIdx is unique.
        EXPECT_EQ(matches[i].queryIdx, expected[i].queryIdx) << i;
        EXPECT_EQ(matches[i].trainIdx, expected[i].trainIdx) << i;
        EXPECT_EQ(matches[i].distance, expected[i].distance) << i;
      }
    }
  }
  // With the defaults, the revisit (42 sees the place of 2) has far more
  // matches than an unrelated place (20).
  const int same = Match(a, b, MatchOptions());
  const int other = Match(a, c, MatchOptions());
  std::printf("defaults: 042 vs 002 (revisit) %d, 042 vs 020 (unrelated) %d\n", same, other);
  EXPECT_GT(same, 3 * other) << same << " vs " << other;
}

// Blocks of different feature types or widths cannot be matched.
TEST(RatioMatcherTest, MixingFeatureTypesOrWidthsThrows) {
  FeatureSet orb;
  orb.type = FeatureType::kOrb;
  orb.descriptors = cv::Mat(2, 32, CV_8U, cv::Scalar(0));
  orb.keypoints.resize(2);
  FeatureSet surf;
  surf.type = FeatureType::kSurf;
  surf.descriptors = cv::Mat(2, 64, CV_32F, cv::Scalar(0));
  surf.keypoints.resize(2);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { Match(orb, surf, MatchOptions()); },
                                          {"cannot match", "orb", "surf"}));
  FeatureSet wide = orb;
  wide.descriptors = cv::Mat(2, 64, CV_8U, cv::Scalar(0));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { Match(orb, wide, MatchOptions()); },
                                          {"widths differ", "32", "64"}));
}

// A view needs one descriptor row per keypoint.
TEST(RatioMatcherTest, MakeDescriptorBlockRejectsKeypointCountMismatch) {
  FeatureSet set = RandomOrb(3, 1);
  set.keypoints.resize(2);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { MakeDescriptorBlock(set, nullptr); },
                                          {"2 keypoints", "3 descriptor rows"}));
  set.keypoints.resize(3);
  const DescriptorBlock block = MakeDescriptorBlock(set, nullptr);
  EXPECT_EQ(block.rows, 3);
  EXPECT_EQ(block.row_bytes, 32);
  EXPECT_EQ(block.Row(2), set.descriptors.ptr<uint8_t>(2));
}

// SURF: descriptors of opposite Laplacian signs never match, even identical
// ones. The query has a single descriptor, so one-to-one and the reverse
// (cross-check) test are trivially passed: the reverse search sees one
// candidate, whose ratio test always passes. The rule is checked alone with
// both flags off, and the defaults must give the same answer.
TEST(RatioMatcherTest, SurfLaplacianSignRejects) {
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
  for (const bool guarded : {false, true}) {
    SCOPED_TRACE(guarded ? "defaults" : "plain rule");
    MatchOptions options = guarded ? MatchOptions() : Plain();
    options.max_l2 = 0;  // the same-sign descriptor is far: no distance limit here
    std::vector<cv::DMatch> matches;
    EXPECT_EQ(MatchDescriptors(MakeDescriptorBlock(q, &lq), MakeDescriptorBlock(d, &ld), options,
                               &matches),
              1);
    ASSERT_EQ(matches.size(), 1u);
    EXPECT_EQ(matches[0].trainIdx, 1);  // the same-sign one, though farther
    EXPECT_NEAR(matches[0].distance, 0.9f - 0.125f, 1e-6f);
    options.use_laplacian_sign = false;
    matches.clear();
    MatchDescriptors(MakeDescriptorBlock(q, &lq), MakeDescriptorBlock(d, &ld), options, &matches);
    // Without the sign the exact copy is nearest (ratio 0 < 0.8 x d2).
    ASSERT_EQ(matches.size(), 1u);
    EXPECT_EQ(matches[0].trainIdx, 0);
    EXPECT_EQ(matches[0].distance, 0.f);
  }
}

// The Hamming limit removes exactly the matches farther than it, with the
// plain rule and with the defaults (a mutual pair's distance is the same both
// ways, so the reverse test applies the same limit).
TEST(RatioMatcherTest, DistanceLimitsRejectFarMatches) {
  const FeatureSet a = Orb(Image(42));
  const FeatureSet b = Orb(Image(2));
  for (const bool guarded : {false, true}) {
    SCOPED_TRACE(guarded ? "defaults" : "plain rule");
    MatchOptions loose = guarded ? MatchOptions() : Plain();
    loose.max_hamming = 0;
    MatchOptions strict = loose;
    strict.max_hamming = 30;
    std::vector<cv::DMatch> matches;
    const int all = Match(a, b, loose, &matches);
    std::vector<cv::DMatch> expected;
    for (const auto& m : matches) {
      if (m.distance <= 30) expected.push_back(m);
    }
    std::vector<cv::DMatch> limited_matches;
    const int limited = Match(a, b, strict, &limited_matches);
    EXPECT_EQ(limited, static_cast<int>(expected.size()));
    ASSERT_EQ(limited_matches.size(), expected.size());
    for (size_t i = 0; i < expected.size(); ++i) {
      EXPECT_EQ(limited_matches[i].queryIdx, expected[i].queryIdx);
      EXPECT_EQ(limited_matches[i].trainIdx, expected[i].trainIdx);
    }
    EXPECT_LT(limited, all);
    EXPECT_GT(limited, 0);
  }
}

// Empty blocks on either side give no matches, for every flag setting.
TEST(RatioMatcherTest, EmptyInputs) {
  FeatureSet empty;
  empty.descriptors = cv::Mat(0, 32, CV_8U);
  const FeatureSet a = Orb(Image(1));
  for (const MatchOptions& options : {MatchOptions(), Plain()}) {
    std::vector<cv::DMatch> matches;
    EXPECT_EQ(Match(empty, a, options, &matches), 0);
    EXPECT_EQ(Match(a, empty, options, &matches), 0);
    EXPECT_TRUE(matches.empty());
  }
}

// One-to-one: N query copies of one keyframe descriptor all match it under the
// plain rule; with one_to_one only one survives, the closest, and among equal
// distances the lowest query index.
TEST(RatioMatcherTest, OneToOneKeepsOneQueryPerKeyframeDescriptor) {
  const int kCopies = 5;
  FeatureSet keyframe = RandomOrb(2, 7);
  // Row 1 is row 0's complement: 256 bits away, so the ratio test on row 0
  // passes for any copy of it.
  for (int c = 0; c < 32; ++c) {
    keyframe.descriptors.at<uint8_t>(1, c) = ~keyframe.descriptors.at<uint8_t>(0, c);
  }
  FeatureSet query;
  query.descriptors = cv::repeat(keyframe.descriptors.row(0), kCopies, 1);
  query.keypoints.resize(kCopies);

  std::vector<cv::DMatch> matches;
  EXPECT_EQ(Match(query, keyframe, Plain(), &matches), kCopies);
  ASSERT_EQ(matches.size(), static_cast<size_t>(kCopies));
  for (int i = 0; i < kCopies; ++i) {
    EXPECT_EQ(matches[i].queryIdx, i);
    EXPECT_EQ(matches[i].trainIdx, 0);
    EXPECT_EQ(matches[i].distance, 0.f);
  }

  MatchOptions one_to_one = Plain();
  one_to_one.one_to_one = true;
  matches.clear();
  EXPECT_EQ(Match(query, keyframe, one_to_one, &matches), 1);
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].queryIdx, 0);  // ties: the lowest query index
  EXPECT_EQ(matches[0].trainIdx, 0);

  // The distance decides before the index: spoil copies 0 and 1 by 3 and 1
  // bits; copy 2 is then the closest (exact) and wins.
  query.descriptors.at<uint8_t>(0, 0) ^= 0x07;
  query.descriptors.at<uint8_t>(1, 5) ^= 0x10;
  matches.clear();
  EXPECT_EQ(Match(query, keyframe, one_to_one, &matches), 1);
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].queryIdx, 2);
  EXPECT_EQ(matches[0].distance, 0.f);
  // With the cross-check on too, the reverse ratio test sees copies 2..4 at
  // distance 0: ambiguous, so nothing is kept.
  EXPECT_EQ(Match(query, keyframe, MatchOptions()), 0);
  // With a single exact copy left, the reverse test passes (0 < 0.8 x 1).
  query.descriptors.at<uint8_t>(3, 9) ^= 0x01;
  query.descriptors.at<uint8_t>(4, 9) ^= 0x01;
  matches.clear();
  EXPECT_EQ(Match(query, keyframe, MatchOptions(), &matches), 1);
  ASSERT_EQ(matches.size(), 1u);
  EXPECT_EQ(matches[0].queryIdx, 2);
}

// The sparse-keyframe guard on real data: a keyframe of only 8 descriptors of
// an unrelated image collects matches from many query descriptors under the
// plain rule (its second neighbour is far, so the ratio test lets almost any
// nearest neighbour through). With the defaults it keeps at most one match
// per row, far below the true revisit's count, and every kept match is mutual.
TEST(RatioMatcherTest, CrossCheckGuardsSparseKeyframe) {
  const int kRows = 8;
  const FeatureSet query = Orb(Image(42));
  const FeatureSet same = Orb(Image(2));
  const FeatureSet sparse = FirstRows(Orb(Image(20)), kRows);
  ASSERT_EQ(sparse.size(), static_cast<size_t>(kRows));

  MatchOptions unlimited_plain = Plain();
  unlimited_plain.max_hamming = 0;
  const int plain_unlimited = Match(query, sparse, unlimited_plain);
  const int plain = Match(query, sparse, Plain());
  MatchOptions one_to_one = Plain();
  one_to_one.one_to_one = true;
  const int only_one_to_one = Match(query, sparse, one_to_one);
  std::vector<cv::DMatch> guarded_matches;
  const int guarded = Match(query, sparse, MatchOptions(), &guarded_matches);
  const int true_match = Match(query, same, MatchOptions());
  std::printf(
      "sparse unrelated keyframe (%d rows of 020) vs 042: plain rule %d (no Hamming limit %d), "
      "one-to-one only %d, defaults %d; true revisit 002: %d\n",
      kRows, plain, plain_unlimited, only_one_to_one, guarded, true_match);

  // Without the guard several query descriptors pile onto the 8 rows.
  EXPECT_GT(plain_unlimited, 4 * kRows);
  EXPECT_GT(plain, kRows);
  EXPECT_GT(plain, guarded);
  // With it: at most one per row, and far below the true match.
  EXPECT_LE(guarded, kRows);
  EXPECT_LE(only_one_to_one, kRows);
  EXPECT_LE(guarded, only_one_to_one);
  EXPECT_GT(true_match, 10 * std::max(guarded, 1));

  // Every guarded match is mutual: t is q's nearest keyframe row and q is t's
  // unique nearest query row (brute force).
  ASSERT_EQ(static_cast<int>(guarded_matches.size()), guarded);
  for (const cv::DMatch& m : guarded_matches) {
    const uint8_t* t_row = sparse.descriptors.ptr<uint8_t>(m.trainIdx);
    const uint8_t* q_row = query.descriptors.ptr<uint8_t>(m.queryIdx);
    const uint32_t d = HammingReference(q_row, t_row, 32);
    EXPECT_EQ(static_cast<float>(d), m.distance);
    for (int q = 0; q < query.descriptors.rows; ++q) {
      if (q == m.queryIdx) continue;
      EXPECT_GT(HammingReference(query.descriptors.ptr<uint8_t>(q), t_row, 32), d)
          << "query row " << q << " is as close to keyframe row " << m.trainIdx << " as "
          << m.queryIdx;
    }
    for (int t = 0; t < kRows; ++t) {
      if (t == m.trainIdx) continue;
      EXPECT_GT(HammingReference(q_row, sparse.descriptors.ptr<uint8_t>(t), 32), d);
    }
  }
  // The guard also applies the limit and ratio test: for the true revisit the
  // guarded count is below the plain one but of the same order.
  const int true_plain = Match(query, same, Plain());
  std::printf("true revisit 002: plain rule %d, defaults %d\n", true_plain, true_match);
  EXPECT_LE(true_match, true_plain);
  EXPECT_GT(true_match, true_plain / 3);
}

// Output invariants for every flag combination: the list is sorted by
// queryIdx, has one entry per query descriptor at most, unique trainIdx
// when one_to_one (or cross_check), and its size is the returned count.
TEST(RatioMatcherTest, MatchListsAreSortedUniqueAndCounted) {
  const FeatureSet query = Orb(Image(42));
  const FeatureSet same = Orb(Image(2));
  const FeatureSet other = Orb(Image(20));
  const FeatureSet sparse = FirstRows(other, 8);
  for (const FeatureSet* db : {&same, &other, &sparse}) {
    for (const bool one_to_one : {false, true}) {
      for (const bool cross_check : {false, true}) {
        for (const int max_hamming : {0, 64}) {
          SCOPED_TRACE(::testing::Message()
                       << "one_to_one " << one_to_one << " cross_check " << cross_check
                       << " max_hamming " << max_hamming << " db rows " << db->size());
          MatchOptions options;
          options.one_to_one = one_to_one;
          options.cross_check = cross_check;
          options.max_hamming = max_hamming;
          std::vector<cv::DMatch> matches;
          const int count = Match(query, *db, options, &matches);
          ASSERT_EQ(static_cast<int>(matches.size()), count);
          // Appends, does not replace.
          std::vector<cv::DMatch> appended(1);
          EXPECT_EQ(Match(query, *db, options, &appended), count);
          EXPECT_EQ(static_cast<int>(appended.size()), count + 1);
          std::set<int> train;
          for (size_t i = 0; i < matches.size(); ++i) {
            if (i > 0) {
              EXPECT_LT(matches[i - 1].queryIdx, matches[i].queryIdx);
            }
            EXPECT_GE(matches[i].trainIdx, 0);
            EXPECT_LT(matches[i].trainIdx, db->descriptors.rows);
            if (max_hamming > 0) {
              EXPECT_LE(matches[i].distance, max_hamming);
            }
            train.insert(matches[i].trainIdx);
          }
          if (one_to_one || cross_check) {
            EXPECT_EQ(train.size(), matches.size());
          }
          if (!one_to_one && !cross_check && db == &sparse) {
            EXPECT_LT(train.size(), matches.size());  // the plain rule piles up
          }
        }
      }
    }
  }
}

// Check() rejects every out-of-range option with a message naming the field,
// the range and the value, and accepts the defaults.
// Guided matching compares a query row only with the keyframe rows of its
// label: a set against itself matches every row; against the same rows
// under other labels, none; a row whose label the keyframe lacks, none.
TEST(RatioMatcherTest, GuidedMatchesCompareOnlyRowsOfOneLabel) {
  const FeatureSet set = RandomOrb(60, 11);
  const DescriptorBlock block = MakeDescriptorBlock(set, nullptr);
  std::vector<uint32_t> labels(60), shifted(60);
  for (uint32_t i = 0; i < 60; ++i) {
    labels[i] = i % 7;
    shifted[i] = i % 7 + 7;
  }
  MatchOptions options = Plain();
  options.max_hamming = 0;
  const GuidedMatcher guided(block, labels.data(), labels.size(), options);
  EXPECT_EQ(guided.Count(block, labels.data(), labels.size()), 60);
  EXPECT_EQ(guided.Count(block, shifted.data(), shifted.size()), 0);
  // One label in common (label 3): only its 9 rows can match.
  std::vector<uint32_t> one(60, 100);
  for (uint32_t i = 3; i < 60; i += 7) one[i] = 3;
  EXPECT_EQ(guided.Count(block, one.data(), one.size()), 9);
  // Against rows of their own label that are not their copies, random
  // descriptors mostly fail the ratio test; never more than the plain rule
  // over all rows finds, which compares them with more rows.
  const FeatureSet other = RandomOrb(60, 12);
  const DescriptorBlock other_block = MakeDescriptorBlock(other, nullptr);
  EXPECT_LE(guided.Count(other_block, labels.data(), labels.size()), 60);
  // Labels must cover the rows; types must agree.
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>(
      [&] { guided.Count(block, labels.data(), 59); }, "one label per keyframe row"));
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>(
      [&] { GuidedMatcher(block, labels.data(), 59, options); }, "one label per query row"));
  FeatureSet surf;
  surf.type = FeatureType::kSurf;
  surf.descriptors = cv::Mat(60, 64, CV_32F, cv::Scalar(0.1f));
  surf.keypoints.resize(60);
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>(
      [&] { guided.Count(MakeDescriptorBlock(surf, nullptr), labels.data(), 60); },
      "cannot match"));
}

TEST(RatioMatcherTest, CheckRejectsOutOfRangeOptions) {
  EXPECT_EQ(MatchOptions().Check(), "");
  EXPECT_EQ(Plain().Check(), "");
  const auto with = [](auto set) {
    MatchOptions o;
    set(o);
    return o.Check();
  };
  const std::string nan_reason =
      with([](MatchOptions& o) { o.ratio = std::numeric_limits<double>::quiet_NaN(); });
  EXPECT_EQ(nan_reason.rfind("`ratio` must be in (0, 1] (got ", 0), 0u) << nan_reason;
  EXPECT_EQ(with([](MatchOptions& o) { o.ratio = 0; }), "`ratio` must be in (0, 1] (got 0)");
  EXPECT_EQ(with([](MatchOptions& o) { o.ratio = 1.5; }), "`ratio` must be in (0, 1] (got 1.5)");
  EXPECT_EQ(with([](MatchOptions& o) { o.ratio = 1.0; }), "");
  EXPECT_EQ(with([](MatchOptions& o) { o.max_hamming = -1; }),
            "`max_hamming` must be in [0, 256] (got -1)");
  EXPECT_EQ(with([](MatchOptions& o) { o.max_hamming = 257; }),
            "`max_hamming` must be in [0, 256] (got 257)");
  EXPECT_EQ(with([](MatchOptions& o) { o.max_hamming = 0; }), "");
  EXPECT_EQ(with([](MatchOptions& o) { o.max_hamming = 256; }), "");
  EXPECT_EQ(with([](MatchOptions& o) { o.max_l2 = -0.1; }), "`max_l2` must be in [0, 2] (got -0.1)");
  EXPECT_EQ(with([](MatchOptions& o) { o.max_l2 = 3; }), "`max_l2` must be in [0, 2] (got 3)");
  EXPECT_EQ(with([](MatchOptions& o) { o.max_l2 = 2; }), "");
}

}  // namespace
}  // namespace placedb
