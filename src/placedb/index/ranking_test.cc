#include "placedb/index/ranking.h"

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

TEST(RankingTest, MergeOfPartitionTopKEqualsTopKOfWhole) {
  int checked = 0;
  for (uint32_t seed = 1; seed <= 200; ++seed) {
    std::mt19937 rng(seed);
    const int n = std::uniform_int_distribution<int>(0, 80)(rng);
    const int parts = std::uniform_int_distribution<int>(1, 6)(rng);
    const int k = std::uniform_int_distribution<int>(1, 12)(rng);
    // Integer scores drawn from a small range (ties are frequent), unique ids.
    std::vector<int32_t> ids(n);
    for (int i = 0; i < n; ++i) ids[i] = i + 1;
    std::shuffle(ids.begin(), ids.end(), rng);
    std::vector<ScoredKeyframe> whole;
    std::vector<std::vector<ScoredKeyframe>> partition(parts);
    std::uniform_int_distribution<int> score(0, seed % 2 == 0 ? 3 : 50);
    std::uniform_int_distribution<int> which(0, parts - 1);
    for (int32_t id : ids) {
      const ScoredKeyframe s{id, static_cast<double>(score(rng))};
      whole.push_back(s);
      partition[which(rng)].push_back(s);
    }
    std::vector<std::vector<ScoredKeyframe>> partial;
    for (auto& part : partition) partial.push_back(TopK(part, k));
    const std::vector<ScoredKeyframe> merged = MergeRankedLists(partial, k);
    const std::vector<ScoredKeyframe> expected = TopK(whole, k);
    ASSERT_EQ(merged, expected) << "seed " << seed << " n " << n << " parts " << parts << " k "
                                << k;
    EXPECT_EQ(merged.size(), std::min<size_t>(n, k));
    ++checked;
  }
  EXPECT_EQ(checked, 200);
}

TEST(RankingTest, MergeKeepsMaxScoreOfDuplicateIds) {
  const std::vector<std::vector<ScoredKeyframe>> lists = {
      {{1, 5}, {2, 9}, {3, 1}},
      {{2, 4}, {1, 7}, {4, 6}},
      {{3, 8}},
  };
  const std::vector<ScoredKeyframe> expected = {{2, 9}, {3, 8}, {1, 7}, {4, 6}};
  EXPECT_EQ(MergeRankedLists(lists, 0), expected);
  const std::vector<ScoredKeyframe> top2 = {{2, 9}, {3, 8}};
  EXPECT_EQ(MergeRankedLists(lists, 2), top2);
  // Duplicate ids inside a single list as well.
  EXPECT_EQ(MergeRankedLists({{{5, 1}, {5, 3}, {5, 2}}}, 5), (std::vector<ScoredKeyframe>{{5, 3}}));
  EXPECT_TRUE(MergeRankedLists({}, 3).empty());
  EXPECT_TRUE(MergeRankedLists({{}, {}}, 3).empty());

  // Randomised: the merge equals the per-id max computed by hand.
  for (uint32_t seed = 1; seed <= 30; ++seed) {
    std::mt19937 rng(seed);
    std::vector<std::vector<ScoredKeyframe>> random_lists(4);
    std::map<int32_t, double> best;
    for (auto& list : random_lists) {
      for (int i = 0; i < 15; ++i) {
        const int32_t id = std::uniform_int_distribution<int>(1, 20)(rng);
        const double s = std::uniform_int_distribution<int>(0, 9)(rng);
        list.push_back({id, s});
        auto it = best.find(id);
        if (it == best.end() || s > it->second) best[id] = s;
      }
    }
    std::vector<ScoredKeyframe> want;
    for (const auto& [id, s] : best) want.push_back({id, s});
    EXPECT_EQ(MergeRankedLists(random_lists, 0), SortedCopy(want)) << "seed " << seed;
  }
}

}  // namespace
}  // namespace placedb
