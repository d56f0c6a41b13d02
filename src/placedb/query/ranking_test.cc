#include "placedb/query/ranking.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>

namespace placedb {
namespace {

std::vector<ScoredKeyframe> SortedCopy(std::vector<ScoredKeyframe> list) {
  std::sort(list.begin(), list.end(), RanksBefore);
  return list;
}

TEST(RankingTest, RanksBeforeOrdersByScoreThenLowerId) {
  EXPECT_TRUE(RanksBefore({7, 3.0}, {1, 2.0}));
  EXPECT_FALSE(RanksBefore({1, 2.0}, {7, 3.0}));
  EXPECT_TRUE(RanksBefore({2, 5.0}, {3, 5.0}));
  EXPECT_FALSE(RanksBefore({3, 5.0}, {2, 5.0}));
  EXPECT_FALSE(RanksBefore({4, 5.0}, {4, 5.0}));  // strict weak order: irreflexive
}

TEST(RankingTest, TopKOrderAndTies) {
  const std::vector<ScoredKeyframe> list = {{5, 10}, {2, 30}, {9, 30}, {1, 10}, {4, 20}, {3, 30}};
  const std::vector<ScoredKeyframe> top3 = TopK(list, 3);
  const std::vector<ScoredKeyframe> expected3 = {{2, 30}, {3, 30}, {9, 30}};
  EXPECT_EQ(top3, expected3);

  const std::vector<ScoredKeyframe> top5 = TopK(list, 5);
  const std::vector<ScoredKeyframe> expected5 = {{2, 30}, {3, 30}, {9, 30}, {4, 20}, {1, 10}};
  EXPECT_EQ(top5, expected5);

  // k <= 0 keeps everything, sorted.
  const std::vector<ScoredKeyframe> all = {{2, 30}, {3, 30}, {9, 30}, {4, 20}, {1, 10}, {5, 10}};
  EXPECT_EQ(TopK(list, 0), all);
  EXPECT_EQ(TopK(list, -3), all);
  // k larger than the list keeps everything.
  EXPECT_EQ(TopK(list, 100), all);
  EXPECT_TRUE(TopK({}, 5).empty());
  EXPECT_TRUE(TopK({}, 0).empty());
}

TEST(RankingTest, TopKMatchesFullSortOnRandomLists) {
  for (uint32_t seed = 1; seed <= 50; ++seed) {
    std::mt19937 rng(seed);
    const int n = std::uniform_int_distribution<int>(0, 60)(rng);
    std::vector<ScoredKeyframe> list;
    for (int i = 0; i < n; ++i) {
      // Few distinct scores: many ties.
      list.push_back(
          {i * 3 + 1, static_cast<double>(std::uniform_int_distribution<int>(0, 5)(rng))});
    }
    std::shuffle(list.begin(), list.end(), rng);
    const std::vector<ScoredKeyframe> sorted = SortedCopy(list);
    for (int k : {0, 1, 3, 10, 70}) {
      std::vector<ScoredKeyframe> expected = sorted;
      if (k > 0 && static_cast<size_t>(k) < expected.size()) expected.resize(k);
      EXPECT_EQ(TopK(list, k), expected) << "seed " << seed << " k " << k;
    }
  }
}

}  // namespace
}  // namespace placedb
