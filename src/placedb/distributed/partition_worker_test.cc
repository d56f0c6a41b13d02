#include "placedb/distributed/partition_worker.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "placedb/builder/testing.h"
#include "placedb/distributed/vote_collector.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {

// rtabmap 1..40 with a bag-of-words index, and the features of 41..84.
class PartitionWorkerTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    tmp_ = new testing_util::TempDir();
    testing_util::BuildSampleDatabase(Dir());
    queries_ = new std::map<uint64_t, FeatureSet>;
    const PlaceDatabase db = PlaceDatabase::Open(Dir());
    for (int id = 41; id <= 84; ++id)
      (*queries_)[id] = db.Extract(cv::imread(testing_util::RtabmapImage(id)));
  }
  static void TearDownTestSuite() {
    delete tmp_;
    delete queries_;
  }
  static std::string Dir() { return tmp_->Path("bow"); }
  static const std::map<uint64_t, FeatureSet>& Queries() { return *queries_; }
  // Bag of words with few candidates: a partition's own best are often not
  // the whole database's.
  static QueryOptions Bow() {
    QueryOptions o;
    o.retrieval.method = RetrievalMethod::kBow;
    o.retrieval.bow_candidates = 8;
    o.retrieval.guided_candidates = 3;
    return o;
  }

  static testing_util::TempDir* tmp_;
  static std::map<uint64_t, FeatureSet>* queries_;
};
testing_util::TempDir* PartitionWorkerTest::tmp_ = nullptr;
std::map<uint64_t, FeatureSet>* PartitionWorkerTest::queries_ = nullptr;

// Workers and the vote in two rounds, every message handed over in a random
// order across frames (as a transport may deliver them): every answer is
// complete and equals the whole database's bag-of-words answer, where the
// one-round merge of the partitions' own answers is not always.
TEST_F(PartitionWorkerTest, TwoRoundsAnswerAsTheWholeDatabase) {
  const PlaceDatabase db = PlaceDatabase::Open(Dir());
  for (const PartitionScheme scheme :
       {PartitionScheme::kInterleaved, PartitionScheme::kContiguous}) {
    const int parts = 3;
    std::vector<BowPartitionWorker> workers;
    for (int p = 0; p < parts; ++p)
      workers.emplace_back(db, KeyframeSubset::Partition(p, parts, scheme), Bow());
    VoteOptions vote;
    vote.num_partitions = parts;
    vote.deadline_ms = 1e5;
    vote.query = Bow();
    VoteCollector collector(vote);
    ASSERT_TRUE(collector.two_rounds());
    // Messages in flight: a shortlist or an answer of (frame, partition).
    struct Message {
      uint64_t seq;
      int partition;
      bool answer;
      Shortlist shortlist;
      QueryResult result;
    };
    std::vector<Message> flight;
    for (const auto& [seq, f] : Queries()) {
      for (int p = 0; p < parts; ++p) {
        Message m{seq, p, false, workers[p].MakeShortlist(seq, f), {}};
        // A worker answers in one round: refused before the candidates.
        EXPECT_EQ(collector.OnPartial(seq, p, QueryResult(), 0.0), VoteStatus::kUnexpected);
        flight.push_back(std::move(m));
      }
    }
    std::mt19937 rng(11);
    std::map<uint64_t, FrameAnswer> answers;
    while (!flight.empty()) {
      std::uniform_int_distribution<size_t> pick(0, flight.size() - 1);
      const size_t i = pick(rng);
      Message m = std::move(flight[i]);
      flight.erase(flight.begin() + static_cast<std::ptrdiff_t>(i));
      if (m.answer) {
        ASSERT_EQ(collector.OnPartial(m.seq, m.partition, m.result, 0.0), VoteStatus::kAccepted);
      } else {
        ASSERT_EQ(collector.OnShortlist(m.seq, m.partition, m.shortlist, 0.0),
                  VoteStatus::kAccepted);
      }
      for (const FrameCandidates& c : collector.PollCandidates(0.0)) {
        EXPECT_EQ(c.merged, (std::vector<int>{0, 1, 2}));
        for (int p = 0; p < parts; ++p)
          flight.push_back(
              {c.frame_seq, p, true, {}, workers[p].Answer(c.frame_seq, c.candidates)});
      }
      for (FrameAnswer& a : collector.Poll(0.0)) answers[a.frame_seq] = std::move(a);
    }
    ASSERT_EQ(answers.size(), Queries().size());
    int one_round_differs = 0;
    for (const auto& [seq, f] : Queries()) {
      const QueryResult expected = db.Query(f, Bow());
      const FrameAnswer& a = answers.at(seq);
      EXPECT_TRUE(a.complete()) << "frame " << seq;
      EXPECT_EQ(a.result.ranked, expected.ranked) << "frame " << seq;
      EXPECT_EQ(a.result.matched, expected.matched) << "frame " << seq;
      std::vector<QueryResult> one_round;
      for (const BowPartitionWorker& w : workers)
        one_round.push_back(db.QueryAmong(f, w.keyframe_ids(), Bow().ForPartition()));
      one_round_differs += !(MergeQueryResults(one_round, Bow()).ranked == expected.ranked);
    }
    EXPECT_GT(one_round_differs, 0) << PartitionSchemeName(scheme);
    for (const BowPartitionWorker& w : workers) EXPECT_EQ(w.pending(), 0u);
  }
}

// A worker keeps max_pending frames between the rounds, answers each once,
// and refuses candidates of another database; it needs a partition, bag of
// words and a session on the whole database.
TEST_F(PartitionWorkerTest, BadRoundsAndSetupsAreRefused) {
  const PlaceDatabase db = PlaceDatabase::Open(Dir());
  BowPartitionWorker w(db, KeyframeSubset::Partition(1, 2), Bow(), /*max_pending=*/2);
  EXPECT_EQ(w.keyframe_ids().size(), 20u);
  const FeatureSet& f = Queries().at(41);
  const Shortlist s = w.MakeShortlist(1, f);
  ASSERT_FALSE(s.bow.empty());
  for (const ShortlistEntry& e : s.bow) EXPECT_GE(e.keyframe_id, 21);  // partition 1 of 2
  w.MakeShortlist(2, f);
  w.MakeShortlist(3, f);  // frame 1 forgotten
  EXPECT_EQ(w.pending(), 2u);
  EXPECT_TRUE(
      testing_util::ThrowsWith<InvalidArgument>([&] { w.Answer(1, s.bow); }, "no features kept"));
  std::vector<ShortlistEntry> forged = s.bow;
  forged[0].keyframe_id += 1;
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>([&] { w.Answer(2, forged); },
                                                        "is not this database's"));
  forged[0] = s.bow[0];
  forged[0].index = 40;
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>([&] { w.Answer(2, forged); },
                                                        "is not this database's"));
  // Candidates none of which are its own: an empty answer, sent all the same.
  const QueryResult none = w.Answer(3, {ShortlistEntry{0, 1, 0.5, -1}});
  EXPECT_TRUE(none.ranked.empty());
  EXPECT_EQ(none.num_examined, 0u);
  EXPECT_TRUE(
      testing_util::ThrowsWith<InvalidArgument>([&] { w.Answer(3, {}); }, "no features kept"));

  QueryOptions exhaustive;
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>(
      [&] { BowPartitionWorker(db, KeyframeSubset::Partition(0, 2), exhaustive); },
      "bag-of-words"));
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>(
      [&] { BowPartitionWorker(db, KeyframeSubset::All(), Bow()); }, "partition I/N"));
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>(
      [&] { BowPartitionWorker(db, KeyframeSubset::Partition(0, 2), Bow(), 0); }, "max_pending"));
  OpenOptions subset;
  subset.subset = KeyframeSubset::Partition(0, 2);
  const PlaceDatabase part = PlaceDatabase::Open(Dir(), subset);
  EXPECT_TRUE(testing_util::ThrowsWith<InvalidArgument>(
      [&] { BowPartitionWorker(part, KeyframeSubset::Partition(0, 2), Bow()); }, "whole database"));
}

}  // namespace
}  // namespace placedb
