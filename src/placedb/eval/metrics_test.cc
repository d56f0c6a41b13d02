#include "placedb/eval/metrics.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <vector>

namespace placedb {
namespace {

TEST(MetricsTest, PercentilesInterpolateLikeNumpy) {
  // numpy.percentile([1, 2, 3, 4], [50, 99]) = [2.5, 3.97]
  EXPECT_DOUBLE_EQ(Percentile({4, 1, 3, 2}, 50), 2.5);
  EXPECT_NEAR(Percentile({4, 1, 3, 2}, 99), 3.97, 1e-12);
  EXPECT_DOUBLE_EQ(Percentile({7}, 99), 7.0);
  EXPECT_DOUBLE_EQ(Percentile({}, 50), 0.0);
}

TEST(MetricsTest, LatencyStats) {
  const LatencyStats s = ComputeLatencyStats({10, 20, 30, 40, 100});
  EXPECT_DOUBLE_EQ(s.mean, 40.0);
  EXPECT_DOUBLE_EQ(s.p50, 30.0);
  EXPECT_DOUBLE_EQ(s.max, 100.0);
  EXPECT_NEAR(s.p99, 97.6, 1e-9);
}

// Shorthands for hand-made answers.
ScoredAnswer Right(double score) { return {true, score, true}; }
ScoredAnswer Wrong(double score) { return {true, score, false}; }
ScoredAnswer Nothing() { return {false, 0.0, false}; }

void ExpectPoint(const PrPoint& p, double threshold, int answered, double precision,
                 double recall) {
  EXPECT_DOUBLE_EQ(p.threshold, threshold);
  EXPECT_EQ(p.answered, answered) << "at " << threshold;
  EXPECT_DOUBLE_EQ(p.precision, precision) << "at " << threshold;
  EXPECT_DOUBLE_EQ(p.recall, recall) << "at " << threshold;
}

// A perfect ranking: every correct answer scores above every wrong one.
// Scores 40 R, 30 R, 20 W, 10 W, 2 positives:
//   t=40: 1 given, 1 right: P 1,   R 0.5
//   t=30: 2 given, 2 right: P 1,   R 1
//   t=20: 3 given, 2 right: P 2/3, R 1
//   t=10: 4 given, 2 right: P 1/2, R 1
// AP = 0.5 * 1 + 0.5 * 1 + 0 + 0 = 1; recall at full precision 1.
TEST(MetricsTest, PerfectRankingHasFullAveragePrecision) {
  const PrecisionRecall pr =
      ComputePrecisionRecall({Wrong(10), Right(40), Wrong(20), Right(30)}, 2, 25.0);
  ASSERT_EQ(pr.curve.size(), 4u);
  ExpectPoint(pr.curve[0], 40, 1, 1.0, 0.5);
  ExpectPoint(pr.curve[1], 30, 2, 1.0, 1.0);
  ExpectPoint(pr.curve[2], 20, 3, 2.0 / 3, 1.0);
  ExpectPoint(pr.curve[3], 10, 4, 0.5, 1.0);
  EXPECT_DOUBLE_EQ(pr.average_precision, 1.0);
  EXPECT_DOUBLE_EQ(pr.recall_at_full_precision, 1.0);
  // Threshold 25 gives the two right answers only.
  ExpectPoint(pr.at_threshold, 25, 2, 1.0, 1.0);
}

// Right and wrong answers interleaved. Scores 50 R, 40 W, 30 R, 20 W, 10 R,
// 3 positives:
//   t=50: 1 given, 1 right: P 1,   R 1/3
//   t=40: 2 given, 1 right: P 1/2, R 1/3
//   t=30: 3 given, 2 right: P 2/3, R 2/3
//   t=20: 4 given, 2 right: P 1/2, R 2/3
//   t=10: 5 given, 3 right: P 3/5, R 1
// AP = 1/3 * 1 + 1/3 * 2/3 + 1/3 * 3/5 = 34/45; recall at full precision 1/3.
TEST(MetricsTest, InterleavedRanking) {
  const PrecisionRecall pr =
      ComputePrecisionRecall({Right(30), Wrong(40), Right(10), Right(50), Wrong(20)}, 3, 30.0);
  ASSERT_EQ(pr.curve.size(), 5u);
  ExpectPoint(pr.curve[0], 50, 1, 1.0, 1.0 / 3);
  ExpectPoint(pr.curve[1], 40, 2, 0.5, 1.0 / 3);
  ExpectPoint(pr.curve[2], 30, 3, 2.0 / 3, 2.0 / 3);
  ExpectPoint(pr.curve[3], 20, 4, 0.5, 2.0 / 3);
  ExpectPoint(pr.curve[4], 10, 5, 0.6, 1.0);
  EXPECT_NEAR(pr.average_precision, 34.0 / 45, 1e-12);
  EXPECT_DOUBLE_EQ(pr.recall_at_full_precision, 1.0 / 3);
  // A threshold equal to a score includes that answer: the t=30 point.
  ExpectPoint(pr.at_threshold, 30, 3, 2.0 / 3, 2.0 / 3);
}

// Equal scores are one threshold: they are given or withheld together, so
// the curve has one point per distinct score. Scores 20 R, 20 W, 20 R, 10 R,
// 4 positives:
//   t=20: 3 given, 2 right: P 2/3, R 1/2
//   t=10: 4 given, 3 right: P 3/4, R 3/4
// AP = 1/2 * 2/3 + 1/4 * 3/4 = 25/48; no threshold gives precision 1, so
// recall at full precision is 0.
TEST(MetricsTest, TiedScoresShareOnePoint) {
  const PrecisionRecall pr =
      ComputePrecisionRecall({Right(20), Wrong(20), Right(10), Right(20)}, 4, 15.0);
  ASSERT_EQ(pr.curve.size(), 2u);
  ExpectPoint(pr.curve[0], 20, 3, 2.0 / 3, 0.5);
  ExpectPoint(pr.curve[1], 10, 4, 0.75, 0.75);
  EXPECT_NEAR(pr.average_precision, 25.0 / 48, 1e-12);
  EXPECT_DOUBLE_EQ(pr.recall_at_full_precision, 0.0);
  // 15 lies between the scores: the three answers at 20.
  ExpectPoint(pr.at_threshold, 15, 3, 2.0 / 3, 0.5);
}

// Queries where nothing was ranked give no answer at any threshold (even 0)
// and add no point to the curve, whatever their score field holds; they
// still count as positives when they had a true match. Answers 15 R, 5 W and
// two empty ones (one with a stray score of 100), 3 positives:
//   t=15: 1 given, 1 right: P 1,   R 1/3
//   t=5:  2 given, 1 right: P 1/2, R 1/3
// AP = 1/3 * 1 + 0 = 1/3; recall at full precision 1/3.
TEST(MetricsTest, QueriesWithoutAnswerAreNeverGiven) {
  ScoredAnswer stray = Nothing();
  stray.score = 100;
  const PrecisionRecall pr =
      ComputePrecisionRecall({Right(15), Nothing(), stray, Wrong(5)}, 3, 0.0);
  ASSERT_EQ(pr.curve.size(), 2u);
  ExpectPoint(pr.curve[0], 15, 1, 1.0, 1.0 / 3);
  ExpectPoint(pr.curve[1], 5, 2, 0.5, 1.0 / 3);
  EXPECT_DOUBLE_EQ(pr.average_precision, 1.0 / 3);
  EXPECT_DOUBLE_EQ(pr.recall_at_full_precision, 1.0 / 3);
  // Threshold 0 gives every answer there is, still not the empty ones.
  ExpectPoint(pr.at_threshold, 0, 2, 0.5, 1.0 / 3);
}

// No positives (every query is a new place): every answer is wrong, recall
// is 0 everywhere (never a division by zero), and AP is 0. Scores 30 W,
// 10 W:
//   t=30: 1 given, 0 right: P 0, R 0
//   t=10: 2 given, 0 right: P 0, R 0
// Above every score nothing is given: precision 1 by definition, recall 0.
TEST(MetricsTest, NoPositives) {
  const PrecisionRecall pr = ComputePrecisionRecall({Wrong(30), Wrong(10)}, 0, 50.0);
  ASSERT_EQ(pr.curve.size(), 2u);
  ExpectPoint(pr.curve[0], 30, 1, 0.0, 0.0);
  ExpectPoint(pr.curve[1], 10, 2, 0.0, 0.0);
  EXPECT_DOUBLE_EQ(pr.average_precision, 0.0);
  EXPECT_DOUBLE_EQ(pr.recall_at_full_precision, 0.0);
  ExpectPoint(pr.at_threshold, 50, 0, 1.0, 0.0);

  // No answers at all: an empty curve, and the same empty operating point.
  const PrecisionRecall none = ComputePrecisionRecall({}, 0, 12.0);
  EXPECT_TRUE(none.curve.empty());
  EXPECT_DOUBLE_EQ(none.average_precision, 0.0);
  EXPECT_DOUBLE_EQ(none.recall_at_full_precision, 0.0);
  ExpectPoint(none.at_threshold, 12, 0, 1.0, 0.0);
}

// The operating point at any threshold, on the interleaved answers above
// (50 R, 40 W, 30 R, 20 W, 10 R; 3 positives): it counts the answers with
// score >= threshold, and it does not depend on the curve's points.
//   t=60: 0 given:           P 1,   R 0
//   t=35: 50, 40 given:      P 1/2, R 1/3
//   t=10: all 5 given:       P 3/5, R 1
//   t=0:  all 5 given:       P 3/5, R 1
TEST(MetricsTest, OperatingPointAtThreshold) {
  const std::vector<ScoredAnswer> answers = {Right(50), Wrong(40), Right(30), Wrong(20), Right(10)};
  ExpectPoint(ComputePrecisionRecall(answers, 3, 60).at_threshold, 60, 0, 1.0, 0.0);
  ExpectPoint(ComputePrecisionRecall(answers, 3, 35).at_threshold, 35, 2, 0.5, 1.0 / 3);
  ExpectPoint(ComputePrecisionRecall(answers, 3, 10).at_threshold, 10, 5, 0.6, 1.0);
  ExpectPoint(ComputePrecisionRecall(answers, 3, 0).at_threshold, 0, 5, 0.6, 1.0);
  // The threshold changes only the operating point, not the curve or AP.
  const PrecisionRecall a = ComputePrecisionRecall(answers, 3, 60);
  const PrecisionRecall b = ComputePrecisionRecall(answers, 3, 0);
  ASSERT_EQ(a.curve.size(), b.curve.size());
  EXPECT_DOUBLE_EQ(a.average_precision, b.average_precision);
  // More positives than right answers caps recall: 3 right of 6 positives.
  ExpectPoint(ComputePrecisionRecall(answers, 6, 0).at_threshold, 0, 5, 0.6, 0.5);
}

}  // namespace
}  // namespace placedb
