#include "placedb/distributed/vote_collector.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "placedb/dataset/image_folder.h"
#include "placedb/builder/builder.h"
#include "placedb/session/place_database.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {

// A partial result ranking one keyframe (id, matches, inliers).
QueryResult Partial(int32_t id, int matches, int inliers) {
  QueryResult r;
  RankedKeyframe k;
  k.keyframe_id = id;
  k.num_matches = matches;
  k.num_inliers = inliers;
  k.score = inliers;
  r.ranked.push_back(k);
  r.num_keyframes = 10;
  r.num_examined = 10;
  return r;
}

VoteOptions Three() {
  VoteOptions o;
  o.num_partitions = 3;
  o.deadline_ms = 100;
  return o;
}

// All partitions answered: the frame is answered at once, complete, merged
// by the voting function.
TEST(VoteCollectorTest, CompleteFramesAreAnsweredAtOnce) {
  VoteCollector c(Three());
  c.OnFrame(7, 0.0);
  EXPECT_EQ(c.OnPartial(7, 2, Partial(30, 40, 35), 1.0), VoteStatus::kAccepted);
  EXPECT_EQ(c.OnPartial(7, 0, Partial(10, 50, 20), 2.0), VoteStatus::kAccepted);
  EXPECT_TRUE(c.Poll(2.5).empty());
  EXPECT_EQ(c.OnPartial(7, 1, Partial(20, 45, 44), 3.0), VoteStatus::kAccepted);
  const std::vector<FrameAnswer> ready = c.Poll(3.0);
  ASSERT_EQ(ready.size(), 1u);
  const FrameAnswer& a = ready[0];
  EXPECT_EQ(a.frame_seq, 7u);
  EXPECT_TRUE(a.complete());
  EXPECT_EQ(a.answered, (std::vector<int>{0, 1, 2}));
  EXPECT_DOUBLE_EQ(a.waited_ms, 3.0);
  ASSERT_TRUE(a.result.matched);
  EXPECT_EQ(a.result.best()->keyframe_id, 20);  // the most inliers
  EXPECT_EQ(a.result.num_keyframes, 30u);
  EXPECT_EQ(c.pending(), 0u);
  EXPECT_TRUE(c.Poll(500).empty());  // answered once
}

// A partition that never answers: at the deadline the frame is answered
// with what there is, and the missing partition is named.
TEST(VoteCollectorTest, DeadlineAnswersWithWhatArrived) {
  VoteCollector c(Three());
  c.OnFrame(1, 10.0);
  c.OnPartial(1, 0, Partial(10, 50, 20), 11.0);
  c.OnPartial(1, 2, Partial(30, 40, 35), 12.0);
  EXPECT_TRUE(c.Poll(109.9).empty());
  const std::vector<FrameAnswer> ready = c.Poll(110.0);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_FALSE(ready[0].complete());
  EXPECT_EQ(ready[0].missing, (std::vector<int>{1}));
  EXPECT_EQ(ready[0].answered, (std::vector<int>{0, 2}));
  EXPECT_EQ(ready[0].result.best()->keyframe_id, 30);
  // No partial at all: still answered, "no match", every partition missing.
  c.OnFrame(2, 200.0);
  const std::vector<FrameAnswer> none = c.Poll(300.0);
  ASSERT_EQ(none.size(), 1u);
  EXPECT_FALSE(none[0].result.matched);
  EXPECT_EQ(none[0].missing, (std::vector<int>{0, 1, 2}));
}

// Late, duplicate and unknown-partition results are refused, and a late
// frame never holds up later ones.
TEST(VoteCollectorTest, LateDuplicateAndUnknownAreRefused) {
  VoteCollector c(Three());
  c.OnFrame(1, 0.0);
  c.OnFrame(2, 0.0);
  for (int p = 0; p < 3; ++p) c.OnPartial(2, p, Partial(10 + p, 10, 5), 1.0);
  EXPECT_EQ(c.OnPartial(1, 5, Partial(1, 1, 1), 1.0), VoteStatus::kUnknownPartition);
  EXPECT_EQ(c.OnPartial(1, -1, Partial(1, 1, 1), 1.0), VoteStatus::kUnknownPartition);
  EXPECT_EQ(c.OnPartial(1, 0, Partial(1, 1, 1), 1.0), VoteStatus::kAccepted);
  EXPECT_EQ(c.OnPartial(1, 0, Partial(1, 1, 1), 1.0), VoteStatus::kDuplicate);
  // Frame 2 is complete and answered while frame 1 waits for its deadline.
  std::vector<FrameAnswer> ready = c.Poll(2.0);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_EQ(ready[0].frame_seq, 2u);
  EXPECT_EQ(c.OnPartial(2, 0, Partial(1, 1, 1), 3.0), VoteStatus::kLate);
  ready = c.Poll(100.0);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_EQ(ready[0].frame_seq, 1u);
  EXPECT_EQ(c.OnPartial(1, 1, Partial(1, 1, 1), 101.0), VoteStatus::kLate);
  // A frame first seen after a newer one was answered is stale.
  c.OnFrame(0, 102.0);
  EXPECT_EQ(c.pending(), 0u);
  EXPECT_EQ(c.OnPartial(0, 1, Partial(1, 1, 1), 102.0), VoteStatus::kLate);
  // A newer frame is fine.
  EXPECT_EQ(c.OnPartial(3, 1, Partial(1, 1, 1), 103.0), VoteStatus::kAccepted);
}

// Too many frames waiting: the oldest are answered now, in frame order.
TEST(VoteCollectorTest, TheOldestAreAnsweredWhenTooManyWait) {
  VoteOptions o = Three();
  o.max_pending = 4;
  VoteCollector c(o);
  for (uint64_t f = 10; f < 16; ++f) c.OnFrame(f, 0.0);
  const std::vector<FrameAnswer> ready = c.Poll(1.0);
  ASSERT_EQ(ready.size(), 2u);
  EXPECT_EQ(ready[0].frame_seq, 10u);
  EXPECT_EQ(ready[1].frame_seq, 11u);
  EXPECT_EQ(c.pending(), 4u);
}

// The feed starting over (sequence numbers far below those answered) resets
// the collector instead of refusing every frame as late.
TEST(VoteCollectorTest, AFeedThatStartsOverIsFollowed) {
  VoteOptions o = Three();
  o.max_pending = 8;
  VoteCollector c(o);
  for (uint64_t f = 0; f < 50; ++f) c.OnFrame(f, 0.0);
  EXPECT_EQ(c.Poll(1000).size(), 50u);
  EXPECT_EQ(c.OnPartial(45, 0, Partial(1, 1, 1), 1001), VoteStatus::kLate);     // just stale
  EXPECT_EQ(c.OnPartial(0, 0, Partial(1, 1, 1), 1001), VoteStatus::kAccepted);  // a new run
  EXPECT_EQ(c.pending(), 1u);
}

TEST(VoteCollectorTest, OptionsAreChecked) {
  VoteOptions o;
  EXPECT_EQ(o.Check(), "");
  o.num_partitions = 0;
  EXPECT_NE(o.Check().find("`partitions`"), std::string::npos);
  o = VoteOptions();
  o.deadline_ms = 0;
  EXPECT_NE(o.Check().find("deadline_ms"), std::string::npos);
  o.deadline_ms = std::nan("");
  EXPECT_THROW(VoteCollector{o}, InvalidArgument);
}

// Real partitions of a built database, their partial results handed in in a
// random order: every complete answer equals the whole database's query.
TEST(VoteCollectorTest, CompleteAnswersEqualTheWholeDatabase) {
  testing_util::TempDir tmp;
  BuildOptions build;
  build.threads = 2;
  build.progress = false;
  const std::string images = PLACEDB_DATA_DIR "/rtabmap_loop/images";
  BuildDatabase(ListImageFolder(images, 1, 40), build, tmp.Path("db"), "rtabmap 1..40");
  const PlaceDatabase whole = PlaceDatabase::Open(tmp.Path("db"));
  std::vector<PlaceDatabase> parts;
  for (int p = 0; p < 3; ++p) {
    OpenOptions o;
    o.subset = KeyframeSubset::Partition(p, 3, PartitionScheme::kInterleaved);
    parts.push_back(PlaceDatabase::Open(tmp.Path("db"), o));
  }
  VoteOptions vote = Three();
  VoteCollector c(vote);
  std::mt19937 rng(5);
  std::map<uint64_t, QueryResult> expected;
  struct Arrival {
    uint64_t seq;
    int partition;
    QueryResult result;
  };
  std::vector<Arrival> arrivals;
  for (int q = 41; q <= 84; q += 4) {
    const FeatureSet f = whole.Extract(cv::imread(testing_util::RtabmapImage(q)));
    expected[q] = whole.Query(f, vote.query);
    for (int p = 0; p < 3; ++p)
      arrivals.push_back(
          {static_cast<uint64_t>(q), p, parts[p].Query(f, vote.query.ForPartition())});
  }
  std::shuffle(arrivals.begin(), arrivals.end(), rng);
  std::vector<FrameAnswer> answers;
  for (const Arrival& a : arrivals) {
    EXPECT_EQ(c.OnPartial(a.seq, a.partition, a.result, 0.0), VoteStatus::kAccepted);
    for (FrameAnswer& ready : c.Poll(0.0)) answers.push_back(std::move(ready));
  }
  ASSERT_EQ(answers.size(), expected.size());
  for (const FrameAnswer& a : answers) {
    EXPECT_TRUE(a.complete());
    EXPECT_EQ(a.result.ranked, expected[a.frame_seq].ranked) << "frame " << a.frame_seq;
    EXPECT_EQ(a.result.matched, expected[a.frame_seq].matched);
  }
}

}  // namespace
}  // namespace placedb
