#include "placedb/feature/spread.h"

#include <gtest/gtest.h>

#include <vector>

#include "placedb/util/error.h"

namespace placedb {
namespace {

// n features at `points` with `responses`; descriptor row i is filled with i.
FeatureSet Features(const std::vector<cv::Point2f>& points, const std::vector<float>& responses) {
  FeatureSet f;
  f.descriptors = cv::Mat(static_cast<int>(points.size()), 32, CV_8U);
  for (size_t i = 0; i < points.size(); ++i) {
    cv::KeyPoint kp(points[i], 31.0f);
    kp.response = responses[i];
    f.keypoints.push_back(kp);
    f.descriptors.row(static_cast<int>(i)).setTo(static_cast<int>(i));
  }
  return f;
}

std::vector<int> Rows(const FeatureSet& f) {
  std::vector<int> rows;
  for (int r = 0; r < f.descriptors.rows; ++r) rows.push_back(f.descriptors.at<uint8_t>(r, 31));
  return rows;
}

TEST(KeepSpreadTest, EveryCellsBestBeforeAnyCellsSecond) {
  // 320 x 240: cells of 40 x 40. Three strong corners in the top-left cell,
  // one weak in the bottom-right, one middling in the centre.
  FeatureSet f = Features({{5, 5}, {10, 10}, {300, 230}, {20, 20}, {170, 130}},
                          {9.0f, 8.0f, 1.0f, 7.0f, 5.0f});
  KeepSpread(&f, 3, {320, 240});
  // Round one: 0 (9), 4 (5), 2 (1); the top-left's second and third wait.
  EXPECT_EQ(Rows(f), (std::vector<int>{0, 2, 4}));  // in their order
  ASSERT_EQ(f.keypoints.size(), 3u);
  EXPECT_EQ(f.keypoints[1].pt, cv::Point2f(300, 230));
  EXPECT_EQ(f.keypoints[2].response, 5.0f);

  FeatureSet g = Features({{5, 5}, {10, 10}, {300, 230}, {20, 20}, {170, 130}},
                          {9.0f, 8.0f, 1.0f, 7.0f, 5.0f});
  KeepSpread(&g, 4, {320, 240});  // round two starts with the strongest second
  EXPECT_EQ(Rows(g), (std::vector<int>{0, 1, 2, 4}));
}

TEST(KeepSpreadTest, NoBudgetOrFewerFeaturesKeepAll) {
  const std::vector<cv::Point2f> points = {{5, 5}, {10, 10}, {300, 230}};
  FeatureSet f = Features(points, {1, 2, 3});
  KeepSpread(&f, 0, {320, 240});
  EXPECT_EQ(Rows(f), (std::vector<int>{0, 1, 2}));
  KeepSpread(&f, 3, {320, 240});
  EXPECT_EQ(Rows(f), (std::vector<int>{0, 1, 2}));
}

TEST(KeepSpreadTest, EqualResponsesKeepTheEarlierAndOutsidePointsCount) {
  // Equal responses: the earlier first. Points off the image (a keypoint
  // tolerance of -1 px, or beyond the size) count in the nearest cell; an
  // unknown size puts everything in one cell.
  FeatureSet f = Features({{-1, -1}, {2, 2}, {400, 300}, {3, 3}}, {1, 1, 1, 1});
  KeepSpread(&f, 2, {320, 240});
  EXPECT_EQ(Rows(f), (std::vector<int>{0, 2}));
  FeatureSet g = Features({{100, 100}, {5, 5}, {300, 200}}, {1, 3, 2});
  KeepSpread(&g, 2, {0, 0});
  EXPECT_EQ(Rows(g), (std::vector<int>{1, 2}));
}

TEST(KeepSpreadTest, AHigherPriorityComesFirstAndSpreadsWithinItself) {
  // The same five as above. Priority 2 for the top-left's two weaker and the
  // bottom-right, 1 for the centre, 0 for the strongest.
  const std::vector<cv::Point2f> points = {{5, 5}, {10, 10}, {300, 230}, {20, 20}, {170, 130}};
  const std::vector<float> responses = {9.0f, 8.0f, 1.0f, 7.0f, 5.0f};
  FeatureSet f = Features(points, responses);
  KeepSpread(&f, 2, {320, 240}, {0, 2, 2, 2, 1});
  // Within priority 2: round one is 1 (8, top-left) and 2 (bottom-right).
  EXPECT_EQ(Rows(f), (std::vector<int>{1, 2}));
  FeatureSet g = Features(points, responses);
  KeepSpread(&g, 4, {320, 240}, {0, 2, 2, 2, 1});  // then 3, then priority 1
  EXPECT_EQ(Rows(g), (std::vector<int>{1, 2, 3, 4}));
  // Equal priorities are spread alone.
  FeatureSet h = Features(points, responses);
  KeepSpread(&h, 3, {320, 240}, {5, 5, 5, 5, 5});
  EXPECT_EQ(Rows(h), (std::vector<int>{0, 2, 4}));
}

TEST(KeepSpreadTest, MismatchedDescriptorsAreAnInternalError) {
  FeatureSet f = Features({{5, 5}, {10, 10}}, {1, 2});
  f.descriptors = f.descriptors.rowRange(0, 1).clone();
  EXPECT_THROW(KeepSpread(&f, 1, {320, 240}), InternalError);
  FeatureSet g = Features({{5, 5}, {10, 10}}, {1, 2});
  EXPECT_THROW(KeepSpread(&g, 1, {320, 240}, {1}), InternalError);
}

}  // namespace
}  // namespace placedb
