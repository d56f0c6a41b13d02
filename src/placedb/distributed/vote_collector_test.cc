#include "placedb/distributed/vote_collector.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "placedb/builder/builder.h"
#include "placedb/dataset/image_folder.h"
#include "placedb/dataset/tum.h"
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

// With `sequence`, each run's answers go through a SequenceMatcher in frame
// order: a path along the keyframe order wins over a stronger stray answer,
// a new run starts a new path, and a frame answered after a newer one
// answers by itself.
TEST(VoteCollectorTest, SequenceEvidenceFollowsEachRun) {
  VoteOptions o;
  o.num_partitions = 2;
  o.deadline_ms = 100;
  o.sequence = true;
  o.sequence_options.min_score = 5;
  VoteCollector c(o);
  c.OnFrame(1, 0.0, "run-a");
  EXPECT_THROW(c.Poll(1000.0), InvalidArgument);  // no keyframe table
  std::vector<Keyframe> table(50);
  for (size_t i = 0; i < table.size(); ++i) table[i].id = static_cast<int32_t>(i + 1);
  VoteCollector v(o);
  v.UseSequence(table);
  // Frames 1..6: partition 0 sees the true keyframe 10 + t (8 inliers),
  // partition 1 a stray keyframe 40 - 3t (9 inliers).
  std::vector<FrameAnswer> answers;
  for (uint64_t t = 1; t <= 6; ++t) {
    v.OnFrame(t, 10.0 * t, "run-a");
    v.OnPartial(t, 0, Partial(static_cast<int32_t>(9 + t), 8, 8), 10.0 * t + 1);
    v.OnPartial(t, 1, Partial(static_cast<int32_t>(43 - 3 * t), 9, 9), 10.0 * t + 2);
    for (FrameAnswer& a : v.Poll(10.0 * t + 3)) answers.push_back(std::move(a));
  }
  ASSERT_EQ(answers.size(), 6u);
  EXPECT_EQ(answers[0].result.decided_by, "frame");
  EXPECT_EQ(answers[0].result.ranked.front().keyframe_id, 40);
  for (size_t i = 2; i < answers.size(); ++i) {
    EXPECT_EQ(answers[i].result.decided_by, "sequence") << i;
    EXPECT_EQ(answers[i].result.ranked.front().keyframe_id, static_cast<int32_t>(10 + i)) << i;
    EXPECT_EQ(answers[i].result.sequence->frame_keyframe_id, static_cast<int32_t>(40 - 3 * i));
  }
  // A new run: the path starts over.
  v.OnFrame(1, 100.0, "run-b");
  v.OnPartial(1, 0, Partial(30, 8, 8), 101.0);
  v.OnPartial(1, 1, Partial(31, 9, 9), 102.0);
  std::vector<FrameAnswer> b = v.Poll(103.0);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_EQ(b[0].run, "run-b");
  EXPECT_EQ(b[0].result.decided_by, "frame");
  EXPECT_EQ(b[0].result.sequence->frames, 1);
  // Frame 2 waits for its deadline while frame 3 is complete: 3 is fed
  // first, and 2, answered after it, answers by itself.
  v.OnFrame(2, 110.0, "run-b");
  v.OnPartial(2, 0, Partial(31, 8, 8), 111.0);
  v.OnFrame(3, 120.0, "run-b");
  v.OnPartial(3, 0, Partial(32, 8, 8), 121.0);
  v.OnPartial(3, 1, Partial(5, 1, 1), 122.0);
  b = v.Poll(123.0);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_EQ(b[0].frame_seq, 3u);
  EXPECT_EQ(b[0].result.decided_by, "sequence");
  b = v.Poll(300.0);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_EQ(b[0].frame_seq, 2u);
  EXPECT_FALSE(b[0].result.sequence.has_value());
  EXPECT_EQ(b[0].result.decided_by, "frame");
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
  // A frame answered is late for its announcement too.
  EXPECT_EQ(c.OnFrame(2, 102.0), VoteStatus::kLate);
  EXPECT_EQ(c.pending(), 0u);
  // A newer frame is fine.
  EXPECT_EQ(c.OnPartial(3, 1, Partial(1, 1, 1), 103.0), VoteStatus::kAccepted);
  EXPECT_EQ(c.stats().answered, 2u);
  EXPECT_EQ(c.stats().complete, 1u);
  EXPECT_EQ(c.stats().partial, 1u);
}

// Frames out of order (a bag played fast, a worker's results before the
// announcement): a frame first seen after a newer one was answered is still
// answered, by its deadline; only frames answered already are late.
TEST(VoteCollectorTest, AFrameSeenAfterANewerOneIsStillAnswered) {
  VoteCollector c(Three());
  EXPECT_EQ(c.OnFrame(0, 0.0), VoteStatus::kAccepted);
  EXPECT_EQ(c.OnFrame(2, 0.0), VoteStatus::kAccepted);
  for (int p = 0; p < 3; ++p) c.OnPartial(2, p, Partial(10 + p, 10, 5), 1.0);
  ASSERT_EQ(c.Poll(1.0).size(), 1u);  // frame 2
  // Frame 1's results come after frame 2 was answered: it waits for the
  // others or its deadline.
  EXPECT_EQ(c.OnPartial(1, 0, Partial(1, 1, 1), 2.0), VoteStatus::kAccepted);
  EXPECT_EQ(c.pending(), 2u);
  const std::vector<FrameAnswer> ready = c.Poll(102.0);
  ASSERT_EQ(ready.size(), 2u);
  EXPECT_EQ(ready[0].frame_seq, 0u);
  EXPECT_EQ(ready[1].frame_seq, 1u);
  EXPECT_EQ(ready[1].answered, (std::vector<int>{0}));
  EXPECT_EQ(c.OnPartial(1, 1, Partial(1, 1, 1), 103.0), VoteStatus::kLate);
  EXPECT_EQ(c.OnPartial(2, 1, Partial(1, 1, 1), 103.0), VoteStatus::kLate);
  EXPECT_EQ(c.stats().answered, 3u);
  EXPECT_EQ(c.stats().complete, 1u);
  EXPECT_EQ(c.stats().partial, 2u);
}

// A second run of the feed (a new run id) into a running collector: its
// frames, numbered from 0 again, are answered, not refused as late; the
// first run's frames still pending are answered at once under its id.
TEST(VoteCollectorTest, ANewRunIsAnswered) {
  VoteCollector c(Three());
  for (uint64_t f = 0; f < 32; ++f) {
    EXPECT_EQ(c.OnFrame(f, 0.0, "run-a"), VoteStatus::kAccepted);
    if (f < 31) {
      for (int p = 0; p < 3; ++p) c.OnPartial(f, p, Partial(10 + p, 10, 5), 0.0);
    }
  }
  std::vector<FrameAnswer> ready = c.Poll(1.0);
  ASSERT_EQ(ready.size(), 31u);
  EXPECT_EQ(ready[30].run, "run-a");
  EXPECT_EQ(c.pending(), 1u);  // frame 31 waits for its partitions
  EXPECT_EQ(c.stats().runs, 1u);
  EXPECT_EQ(c.run(), "run-a");
  // Run b. A result for frame 0 before run b's announcement cannot be told
  // from run a's late one: it is refused. Frame 40's (a number run a did
  // not answer) stays pending for run b.
  EXPECT_EQ(c.OnPartial(0, 0, Partial(7, 10, 5), 2.0), VoteStatus::kLate);
  EXPECT_EQ(c.OnPartial(40, 0, Partial(7, 10, 5), 2.0), VoteStatus::kAccepted);
  EXPECT_EQ(c.OnFrame(0, 2.0, "run-b"), VoteStatus::kAccepted);
  EXPECT_EQ(c.stats().runs, 2u);
  EXPECT_EQ(c.run(), "run-b");
  ready = c.Poll(2.0);
  ASSERT_EQ(ready.size(), 1u);  // run a's frame 31, at once, without its partitions
  EXPECT_EQ(ready[0].frame_seq, 31u);
  EXPECT_EQ(ready[0].run, "run-a");
  EXPECT_FALSE(ready[0].complete());
  for (int p = 0; p < 3; ++p)
    EXPECT_EQ(c.OnPartial(0, p, Partial(7 + p, 10, 5), 3.0), VoteStatus::kAccepted);
  for (int p = 1; p < 3; ++p)
    EXPECT_EQ(c.OnPartial(40, p, Partial(7 + p, 10, 5), 3.0), VoteStatus::kAccepted);
  ready = c.Poll(3.0);
  ASSERT_EQ(ready.size(), 2u);
  EXPECT_EQ(ready[0].frame_seq, 0u);
  EXPECT_EQ(ready[0].run, "run-b");
  EXPECT_TRUE(ready[0].complete());
  EXPECT_EQ(ready[1].frame_seq, 40u);
  EXPECT_TRUE(ready[1].complete());
  for (uint64_t f = 1; f < 32; ++f) {
    EXPECT_EQ(c.OnFrame(f, 4.0, "run-b"), VoteStatus::kAccepted) << f;
    for (int p = 0; p < 3; ++p)
      EXPECT_EQ(c.OnPartial(f, p, Partial(10 + p, 10, 5), 4.0), VoteStatus::kAccepted) << f;
  }
  EXPECT_EQ(c.Poll(4.0).size(), 31u);
  EXPECT_EQ(c.stats().answered, 65u);
  EXPECT_EQ(c.stats().complete, 64u);
  EXPECT_EQ(c.stats().partial, 1u);
}

// The same run id numbering from 0 again (a bag of the feed played twice:
// its announcements keep their run id and numbers) is a new run too.
TEST(VoteCollectorTest, AReplayedBagIsANewRun) {
  VoteCollector c(Three());
  for (uint64_t f = 0; f < 8; ++f) {
    c.OnFrame(f, 0.0, "bag");
    for (int p = 0; p < 3; ++p) c.OnPartial(f, p, Partial(10 + p, 10, 5), 0.0);
  }
  EXPECT_EQ(c.Poll(0.0).size(), 8u);
  EXPECT_EQ(c.OnFrame(0, 1.0, "bag"), VoteStatus::kAccepted);
  EXPECT_EQ(c.stats().runs, 2u);
  for (int p = 0; p < 3; ++p)
    EXPECT_EQ(c.OnPartial(0, p, Partial(10 + p, 10, 5), 1.0), VoteStatus::kAccepted);
  EXPECT_EQ(c.Poll(1.0).size(), 1u);
  // The same announcement again is not a new run.
  EXPECT_EQ(c.OnFrame(0, 2.0, "bag"), VoteStatus::kLate);
  EXPECT_EQ(c.stats().runs, 2u);
}

// Results that cannot be merged (a keyframe in two partitions' results, or
// twice in one; verified where the vote does not verify) are refused, so the
// frame is still answered with the rest.
TEST(VoteCollectorTest, ResultsThatCannotBeMergedAreRefused) {
  VoteCollector c(Three());
  c.OnFrame(1, 0.0);
  EXPECT_EQ(c.OnPartial(1, 0, Partial(10, 50, 20), 1.0), VoteStatus::kAccepted);
  EXPECT_EQ(c.OnPartial(1, 1, Partial(10, 40, 30), 1.0), VoteStatus::kInconsistent);
  QueryResult twice = Partial(20, 40, 30);
  twice.ranked.push_back(twice.ranked[0]);
  EXPECT_EQ(c.OnPartial(1, 1, twice, 1.0), VoteStatus::kInconsistent);
  QueryResult unverified = Partial(20, 40, 30);
  unverified.ranked[0].num_inliers = -1;
  EXPECT_EQ(c.OnPartial(1, 1, unverified, 1.0), VoteStatus::kInconsistent);
  // A score other than the vote's options make of the counts and the
  // whole-image evidence (a worker with another weight, or a forged score).
  QueryResult tilted = Partial(20, 40, 30);
  tilted.ranked[0].whole_image = 0.5;
  tilted.ranked[0].whole_image_z = 5.0;  // 2 above the floor: 30 + 10 x 2 with the defaults
  EXPECT_EQ(c.OnPartial(1, 1, tilted, 1.0), VoteStatus::kInconsistent);
  tilted.ranked[0].score = 30.0 + 25.0;
  EXPECT_EQ(c.OnPartial(1, 1, tilted, 1.0), VoteStatus::kInconsistent);
  tilted.ranked[0].score = 30.0 + 10.0 * 2.0;
  EXPECT_EQ(c.OnPartial(1, 1, tilted, 1.0), VoteStatus::kAccepted);
  EXPECT_EQ(c.OnPartial(1, 2, Partial(30, 40, 35), 1.0), VoteStatus::kAccepted);
  const std::vector<FrameAnswer> ready = c.Poll(1.0);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_TRUE(ready[0].complete());
  EXPECT_EQ(ready[0].result.best()->keyframe_id, 20);  // 30 inliers + 20 of whole image
  EXPECT_STREQ(VoteStatusName(VoteStatus::kInconsistent), "inconsistent");
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
  EXPECT_EQ(c.OnPartial(45, 0, Partial(1, 1, 1), 1002), VoteStatus::kAccepted);  // its frame 45
}

// The voter fills the answer's keyframes from the keyframe table: pose,
// timestamp and source, as the single-process query has them.
TEST(VoteCollectorTest, KeyframesAreDescribedFromTheTable) {
  testing_util::TempDir tmp;
  BuildOptions build;
  build.progress = false;
  BuildDatabase(ReadTumSequence(PLACEDB_DATA_DIR "/tum_fr3_office_mini"), build, tmp.Path("db"),
                "tum");
  const PlaceDatabase whole = PlaceDatabase::Open(tmp.Path("db"));
  OpenOptions table;
  table.keyframe_table = true;
  const PlaceDatabase keyframes = PlaceDatabase::Open(tmp.Path("db"), table);
  const std::optional<Keyframe> k = whole.FindKeyframe(whole.keyframe_ids().at(1));
  ASSERT_TRUE(k && k->pose);
  QueryResult r;
  RankedKeyframe ranked;
  ranked.keyframe_id = k->id;
  r.ranked.push_back(ranked);
  ranked.keyframe_id = 999999;  // not in the database: left as it is
  r.ranked.push_back(ranked);
  DescribeKeyframes(keyframes, &r);
  ASSERT_TRUE(r.ranked[0].pose.has_value());
  EXPECT_EQ(r.ranked[0].pose->translation, k->pose->translation);
  EXPECT_EQ(r.ranked[0].timestamp, k->timestamp);
  EXPECT_GT(r.ranked[0].timestamp, 0.0);
  EXPECT_EQ(r.ranked[0].source, k->source);
  EXPECT_FALSE(r.ranked[0].source.empty());
  EXPECT_FALSE(r.ranked[1].pose.has_value());
  EXPECT_EQ(r.ranked[1].source, "");
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

// Two rounds (bag of words, more than one partition).
VoteOptions TwoRounds(int partitions) {
  VoteOptions o;
  o.num_partitions = partitions;
  o.deadline_ms = 100;
  o.query.retrieval.method = RetrievalMethod::kBow;
  o.query.retrieval.bow_candidates = 2;
  o.query.retrieval.guided_candidates = 0;
  return o;
}

// A shortlist of keyframes (index, bag-of-words score); ids are index + 1.
Shortlist Listed(std::vector<std::pair<uint32_t, double>> entries) {
  Shortlist s;
  for (const auto& [index, score] : entries)
    s.bow.push_back({index, static_cast<int32_t>(index + 1), score, -1});
  return s;
}

// The candidates go out once every shortlist is in, merged as the whole
// database's search would pick them; only then are answers taken, and the
// frame is answered when every partition has answered.
TEST(VoteCollectorTest, TwoRoundsSendCandidatesThenAnswer) {
  VoteCollector c(TwoRounds(2));
  ASSERT_TRUE(c.two_rounds());
  c.OnFrame(4, 0.0);
  const Shortlist a = Listed({{0, 0.9}, {1, 0.2}}), b = Listed({{20, 0.5}, {21, 0.4}});
  EXPECT_EQ(c.OnShortlist(4, 0, a, 1.0), VoteStatus::kAccepted);
  EXPECT_EQ(c.OnShortlist(4, 0, a, 1.0), VoteStatus::kDuplicate);
  EXPECT_EQ(c.OnShortlist(4, 2, b, 1.0), VoteStatus::kUnknownPartition);
  EXPECT_EQ(c.OnPartial(4, 0, Partial(1, 30, 20), 1.5), VoteStatus::kUnexpected);
  EXPECT_TRUE(c.PollCandidates(2.0).empty());
  EXPECT_EQ(c.OnShortlist(4, 1, b, 2.0), VoteStatus::kAccepted);
  const std::vector<FrameCandidates> out = c.PollCandidates(2.0);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].frame_seq, 4u);
  EXPECT_EQ(out[0].merged, (std::vector<int>{0, 1}));
  EXPECT_EQ(out[0].candidates, MergeShortlists({a, b}, TwoRounds(2).query));
  ASSERT_EQ(out[0].candidates.size(), 2u);  // the best 2 of the union
  EXPECT_EQ(out[0].candidates[0].index, 0u);
  EXPECT_EQ(out[0].candidates[1].index, 20u);
  EXPECT_TRUE(c.PollCandidates(3.0).empty());  // once
  EXPECT_EQ(c.OnShortlist(4, 1, b, 3.0), VoteStatus::kLate);
  EXPECT_EQ(c.OnPartial(4, 1, Partial(21, 40, 30), 4.0), VoteStatus::kAccepted);
  EXPECT_TRUE(c.Poll(4.0).empty());
  EXPECT_EQ(c.OnPartial(4, 0, Partial(1, 30, 20), 5.0), VoteStatus::kAccepted);
  const std::vector<FrameAnswer> ready = c.Poll(5.0);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_TRUE(ready[0].complete());
  EXPECT_EQ(ready[0].result.best()->keyframe_id, 21);
  // One round (exhaustive, or one partition): shortlists are not asked for.
  VoteCollector one(Three());
  EXPECT_FALSE(one.two_rounds());
  EXPECT_EQ(one.OnShortlist(4, 0, a, 0.0), VoteStatus::kUnexpected);
  EXPECT_TRUE(one.PollCandidates(1000.0).empty());
  EXPECT_FALSE(VoteCollector(TwoRounds(1)).two_rounds());
}

// At half the deadline the shortlists in are merged; a partition that had
// not sent its shortlist cannot answer (its keyframes were not considered),
// so the frame is answered as soon as the others have, without it.
TEST(VoteCollectorTest, AShortlistMissingAtHalfTheDeadline) {
  VoteCollector c(TwoRounds(3));
  c.OnFrame(9, 0.0);
  EXPECT_EQ(c.OnShortlist(9, 0, Listed({{0, 0.9}}), 0.0), VoteStatus::kAccepted);
  EXPECT_EQ(c.OnShortlist(9, 1, Listed({{15, 0.8}}), 0.0), VoteStatus::kAccepted);
  EXPECT_TRUE(c.PollCandidates(49.0).empty());
  const std::vector<FrameCandidates> out = c.PollCandidates(50.0);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].merged, (std::vector<int>{0, 1}));
  EXPECT_EQ(c.OnShortlist(9, 2, Listed({{30, 0.99}}), 51.0), VoteStatus::kLate);
  EXPECT_EQ(c.OnPartial(9, 2, Partial(31, 50, 45), 52.0), VoteStatus::kUnexpected);
  EXPECT_EQ(c.OnPartial(9, 0, Partial(1, 30, 20), 53.0), VoteStatus::kAccepted);
  EXPECT_TRUE(c.Poll(53.0).empty());
  EXPECT_EQ(c.OnPartial(9, 1, Partial(16, 30, 25), 54.0), VoteStatus::kAccepted);
  const std::vector<FrameAnswer> ready = c.Poll(54.0);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_FALSE(ready[0].complete());
  EXPECT_EQ(ready[0].answered, (std::vector<int>{0, 1}));
  EXPECT_EQ(ready[0].missing, (std::vector<int>{2}));
  EXPECT_EQ(ready[0].result.best()->keyframe_id, 16);
  // No shortlist by the deadline: answered by Poll, every partition missing.
  c.OnFrame(10, 100.0);
  EXPECT_TRUE(c.PollCandidates(160.0).empty());
  const std::vector<FrameAnswer> empty = c.Poll(200.0);
  ASSERT_EQ(empty.size(), 1u);
  EXPECT_EQ(empty[0].missing, (std::vector<int>{0, 1, 2}));
  EXPECT_FALSE(empty[0].result.matched);
}

// What MergeShortlists would refuse is refused as it arrives (a keyframe
// offered with other values); a shortlist cut by its deadline marks the
// answer, whose retrieval time is the slowest shortlist's.
TEST(VoteCollectorTest, ShortlistsThatCannotBeMergedAreRefused) {
  VoteCollector c(TwoRounds(2));
  EXPECT_EQ(c.OnShortlist(1, 0, Listed({{5, 0.5}}), 0.0), VoteStatus::kAccepted);
  EXPECT_EQ(c.OnShortlist(1, 1, Listed({{5, 0.6}}), 0.0), VoteStatus::kInconsistent);
  EXPECT_EQ(c.OnShortlist(1, 1, Listed({{6, 0.6}, {6, 0.7}}), 0.0), VoteStatus::kInconsistent);
  Shortlist late = Listed({{5, 0.5}, {25, 0.4}});  // the same entry twice is no conflict
  late.deadline_reached = true;
  late.retrieve_ms = 7.5;
  EXPECT_EQ(c.OnShortlist(1, 1, late, 0.0), VoteStatus::kAccepted);
  ASSERT_EQ(c.PollCandidates(0.0).size(), 1u);
  EXPECT_EQ(c.OnPartial(1, 0, Partial(6, 20, 15), 0.0), VoteStatus::kAccepted);
  EXPECT_EQ(c.OnPartial(1, 1, QueryResult(), 0.0), VoteStatus::kAccepted);
  const std::vector<FrameAnswer> ready = c.Poll(0.0);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_TRUE(ready[0].complete());
  EXPECT_TRUE(ready[0].result.deadline_reached);
  EXPECT_DOUBLE_EQ(ready[0].result.times.retrieve_ms, 7.5);
  EXPECT_DOUBLE_EQ(ready[0].result.times.total_ms, 7.5);  // + the answers' (0 here)
}

}  // namespace
}  // namespace placedb
