#include "placedb/storage/keyframe_subset.h"

#include <gtest/gtest.h>

#include <vector>

#include "placedb/util/testing.h"

namespace placedb {
namespace {
using testing_util::ThrowsWith;

// Partitions of every size and scheme cover 0..n-1 exactly once; contiguous
// ones are the same ranges the threaded query uses (n p / N).
TEST(KeyframeSubsetTest, PartitionsCoverEveryIndexOnce) {
  for (size_t n : {0u, 1u, 5u, 40u, 101u}) {
    for (int parts = 1; parts <= 8; ++parts) {
      for (const PartitionScheme scheme :
           {PartitionScheme::kContiguous, PartitionScheme::kInterleaved}) {
        std::vector<int> owner(n, -1);
        for (int p = 0; p < parts; ++p) {
          for (const size_t i :
               SelectKeyframes(KeyframeSubset::Partition(p, parts, scheme), n, {})) {
            ASSERT_LT(i, n);
            EXPECT_EQ(owner[i], -1) << "index " << i << " in two parts";
            owner[i] = p;
          }
        }
        for (size_t i = 0; i < n; ++i) {
          ASSERT_GE(owner[i], 0) << "index " << i << " in no part";
          if (scheme == PartitionScheme::kInterleaved) {
            EXPECT_EQ(owner[i], static_cast<int>(i % parts));
          } else {
            EXPECT_GE(i, n * owner[i] / parts);
            EXPECT_LT(i, n * (owner[i] + 1) / parts);
          }
        }
      }
    }
  }
  EXPECT_EQ(SelectKeyframes(KeyframeSubset::Partition(1, 3), 7, {}), (std::vector<size_t>{2, 3}));
  EXPECT_EQ(SelectKeyframes(KeyframeSubset::Partition(1, 3, PartitionScheme::kInterleaved), 7, {}),
            (std::vector<size_t>{1, 4}));
  EXPECT_EQ(SelectKeyframes(KeyframeSubset::All(), 3, {}), (std::vector<size_t>{0, 1, 2}));
}

TEST(KeyframeSubsetTest, IdsSelectTheirIndicesSortedAndUnique) {
  const std::vector<int32_t> ids = {10, 20, 30, 40};
  EXPECT_EQ(SelectKeyframes(KeyframeSubset::Ids({40, 10, 40}), 4, ids),
            (std::vector<size_t>{0, 3}));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] {
        SelectKeyframes(KeyframeSubset::Ids({20, 25}), 4, ids);
      },
      "keyframe id 25"));
}

TEST(KeyframeSubsetTest, CheckAndDescribe) {
  EXPECT_EQ(KeyframeSubset::All().Check(), "");
  EXPECT_EQ(KeyframeSubset::Partition(0, 1).Check(), "");
  EXPECT_NE(KeyframeSubset::Partition(2, 2).Check(), "");
  EXPECT_NE(KeyframeSubset::Partition(-1, 2).Check(), "");
  EXPECT_NE(KeyframeSubset::Partition(0, 0).Check(), "");
  EXPECT_NE(KeyframeSubset::Partition(0, 5000).Check(), "");
  EXPECT_NE(KeyframeSubset::Ids({}).Check(), "");
  EXPECT_EQ(KeyframeSubset::Partition(1, 3, PartitionScheme::kInterleaved).Describe(),
            "partition 1 of 3 (interleaved)");
  EXPECT_EQ(KeyframeSubset::Ids({1, 2}).Describe(), "2 ids");
  EXPECT_EQ(ParsePartitionScheme("interleaved"), PartitionScheme::kInterleaved);
  EXPECT_EQ(PartitionSchemeName(PartitionScheme::kContiguous), std::string("contiguous"));
  EXPECT_THROW(ParsePartitionScheme("random"), InvalidArgument);
}

}  // namespace
}  // namespace placedb
