// The retrieve stage's methods through a session: bag-of-words search,
// cluster search with its fallback, and the deadline.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>

#include "placedb/builder/builder.h"
#include "placedb/builder/testing.h"
#include "placedb/dataset/image_folder.h"
#include "placedb/dataset/match_truth.h"
#include "placedb/feature/whole_image.h"
#include "placedb/query/query.h"
#include "placedb/retrieval/clusters.h"
#include "placedb/retrieval/retriever.h"
#include "placedb/session/place_database.h"
#include "placedb/session/storage_view.h"
#include "placedb/util/file_io.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
using testing_util::RtabmapImage;
using testing_util::ThrowsWith;

namespace fs = std::filesystem;
const std::string kImages = PLACEDB_DATA_DIR "/rtabmap_loop/images";
const std::string kTruth = PLACEDB_DATA_DIR "/rtabmap_loop/ground_truth.csv";

TEST(QueryOptionsTest, DeadlineAndPriorAreChecked) {
  QueryOptions q;
  q.deadline_ms = -1.0;
  EXPECT_FALSE(q.Check().empty());
  q = QueryOptions();
  q.prior.keyframe_id = -3;
  EXPECT_FALSE(q.Check().empty());
}

// rtabmap 1..40 with a bag-of-words index (a small vocabulary: 40 images).
class SearchTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    tmp_ = new testing_util::TempDir();
    testing_util::BuildSampleDatabase(Dir());
    testing_util::BuildSampleDatabase(PlainDir(), IndexKind::kNone);
    queries_ = new std::vector<FeatureSet>;
    const PlaceDatabase db = PlaceDatabase::Open(Dir());
    for (int id = 41; id <= 84; ++id) queries_->push_back(db.Extract(cv::imread(RtabmapImage(id))));
  }
  static void TearDownTestSuite() {
    delete tmp_;
    delete queries_;
  }
  static std::string Dir() { return tmp_->Path("bow"); }
  static std::string PlainDir() { return tmp_->Path("plain"); }
  static const FeatureSet& Features(int id) { return (*queries_)[id - 41]; }

  // Recall@1 over 41..84 (every query has a true match in 1..40).
  static double RecallAt1(const PlaceDatabase& db, QueryOptions options, bool sequence) {
    const MatchTruth truth = ReadMatchTruth(kTruth);
    int correct = 0;
    for (int id = 41; id <= 84; ++id) {
      const QueryResult r = db.Query(Features(id), options);
      const auto it = truth.find(id);
      if (!r.ranked.empty() && it != truth.end() &&
          std::count(it->second.begin(), it->second.end(), r.ranked[0].keyframe_id) > 0) {
        ++correct;
      }
      if (sequence) options.prior.keyframe_id = r.best() ? r.best()->keyframe_id : 0;
    }
    return correct / 44.0;
  }

  static testing_util::TempDir* tmp_;
  static std::vector<FeatureSet>* queries_;
};
testing_util::TempDir* SearchTest::tmp_ = nullptr;
std::vector<FeatureSet>* SearchTest::queries_ = nullptr;

TEST_F(SearchTest, BowFindsWhatExhaustiveSearchFinds) {
  const PlaceDatabase db = PlaceDatabase::Open(Dir());
  ASSERT_NE(StorageView(db).bow_index(), nullptr);
  QueryOptions exhaustive, bow;
  bow.retrieval.method = RetrievalMethod::kBow;
  bow.retrieval.bow_candidates = 10;
  bow.whole_image_candidates = 0;  // bag-of-words' candidates alone
  const double r_exhaustive = RecallAt1(db, exhaustive, false);
  const double r_bow = RecallAt1(db, bow, false);
  EXPECT_GE(r_exhaustive, 0.95);
  EXPECT_GE(r_bow, r_exhaustive - 0.02) << "exhaustive " << r_exhaustive;
  const QueryResult r = db.Query(Features(42), bow);
  EXPECT_EQ(r.search, "bow");
  // 10 bag-of-words candidates, the best 5 by guided matches matched in full.
  ASSERT_EQ(bow.retrieval.guided_candidates, 5);
  EXPECT_EQ(r.num_examined, 5u);
  EXPECT_DOUBLE_EQ(r.coverage, 5.0 / 40.0);
  // Enough candidates, all matched in full: bow examines everything and
  // answers as exhaustive.
  bow.retrieval.bow_candidates = 40;
  bow.retrieval.guided_candidates = 0;
  const QueryResult all = db.Query(Features(42), bow);
  EXPECT_EQ(all.ranked, db.Query(Features(42), exhaustive).ranked);
}

// whole_image_candidates: bag-of-words search also matches the keyframes
// most similar by thumbnail (exactly those, by similarity), and not when the
// restriction (a partition) excludes them; exhaustive search is unchanged.
TEST_F(SearchTest, WholeImageCandidatesJoinBagOfWords) {
  const PlaceDatabase db = PlaceDatabase::Open(Dir());
  ASSERT_EQ(db.whole_image_dims(), 512);  // the default HOG channel
  QueryOptions bow;
  bow.retrieval.method = RetrievalMethod::kBow;
  bow.whole_image_candidates = 0;
  bow.retrieval.bow_candidates = 3;
  bow.retrieval.guided_candidates = 0;  // every candidate matched in full
  bow.min_matches = 1;
  bow.top_k = 40;
  bow.verify.num_candidates = 40;
  const int id = 63;
  const QueryResult without = db.Query(Features(id), bow);
  QueryOptions with = bow;
  with.whole_image_candidates = 4;
  with.whole_image_weight = 1e-9;  // to see every similarity in the answer
  const QueryResult r = db.Query(Features(id), with);
  EXPECT_GT(r.num_examined, without.num_examined);
  EXPECT_LE(r.num_examined, without.num_examined + 4);
  // The 4 most similar keyframes, by brute force over the thumbnails.
  const cv::Mat& q = Features(id).whole_image;
  std::vector<std::pair<double, int32_t>> all;
  {
    const StorageView view(db);
    const Database& d = view.database();
    for (size_t i = 0; i < d.size(); ++i) {
      all.emplace_back(WholeImageSimilarity(q.ptr<int8_t>(), d.WholeImage(i), d.whole_image_dims()),
                       d.keyframe(i).id);
    }
  }
  std::sort(all.begin(), all.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  std::set<int32_t> ranked;
  for (const RankedKeyframe& k : r.ranked) ranked.insert(k.keyframe_id);
  for (size_t i = 0; i < 4; ++i) EXPECT_EQ(ranked.count(all[i].second), 1u) << all[i].second;
  // Exhaustive search is the same with or without candidates.
  QueryOptions exhaustive, exhaustive_with;
  exhaustive.whole_image_candidates = 0;
  exhaustive_with.whole_image_candidates = 4;
  EXPECT_EQ(db.Query(Features(id), exhaustive).ranked,
            db.Query(Features(id), exhaustive_with).ranked);
}

// Whole-image scoring without whole-image candidates examines bow's
// candidates alone; each ranked keyframe's similarity and its
// standardisation over every keyframe are the brute-force ones, and its
// score follows the rule (PartitionedBowIsExactInTwoRounds: the answers
// equal the merged partitions', whose parts compute them the same way).
TEST_F(SearchTest, WholeImageScoringAloneScoresTheExamined) {
  const PlaceDatabase db = PlaceDatabase::Open(Dir());
  QueryOptions bow;
  bow.retrieval.method = RetrievalMethod::kBow;
  bow.retrieval.bow_candidates = 8;
  bow.retrieval.guided_candidates = 0;
  bow.whole_image_weight = 5.0;
  bow.whole_image_floor = 1.0;
  bow.whole_image_candidates = 0;
  bow.top_k = 40;
  bow.verify.num_candidates = 40;
  const StorageView view(db);
  const Database& d = view.database();
  int compared = 0, with_bonus = 0;
  for (int id = 41; id <= 84; id += 3) {
    const cv::Mat& q = Features(id).whole_image;
    std::vector<double> all;
    for (size_t i = 0; i < d.size(); ++i)
      all.push_back(WholeImageSimilarity(q.ptr<int8_t>(), d.WholeImage(i), d.whole_image_dims()));
    double mean = 0, var = 0;
    for (const double v : all) mean += v / all.size();
    for (const double v : all) var += (v - mean) * (v - mean) / all.size();
    const QueryResult r = db.Query(Features(id), bow);
    EXPECT_EQ(r.num_examined, 8);
    for (const RankedKeyframe& k : r.ranked) {
      ASSERT_TRUE(k.whole_image.has_value()) << "query " << id;
      const double s = all[static_cast<size_t>(k.keyframe_id - 1)];
      EXPECT_NEAR(*k.whole_image, s, 1e-5);
      EXPECT_NEAR(*k.whole_image_z, (s - mean) / std::sqrt(var), 1e-4);
      EXPECT_DOUBLE_EQ(k.score, k.num_inliers + 5.0 * std::max(0.0, *k.whole_image_z - 1.0));
      with_bonus += *k.whole_image_z > 1.0;
      ++compared;
    }
  }
  EXPECT_GT(compared, 15);
  EXPECT_GT(with_bonus, 3);
}

// Scoring a few keyframes one by one gives the inverted file's scores.
TEST_F(SearchTest, ScoringEachKeyframeEqualsTheInvertedFile) {
  const PlaceDatabase db = PlaceDatabase::Open(Dir());
  const StorageView view(db);
  const GrowingBowIndex& bow = *view.bow_index();
  const std::vector<uint32_t> among = {0, 3, 4, 5, 17, 30, 39};
  for (int id = 41; id <= 84; ++id) {
    std::vector<int8_t> laplacian;
    const BowVector q = bow.Transform(MakeDescriptorBlock(Features(id), &laplacian));
    const auto a = bow.ScoreEach(q, 4, among);
    const auto b = bow.base().Query(q, 4, &among);
    ASSERT_EQ(a.size(), b.size()) << id;
    for (size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a[i].index, b[i].index) << id;
      EXPECT_EQ(a[i].score, b[i].score) << id;
    }
  }
}

TEST_F(SearchTest, BowNeedsAnIndex) {
  const PlaceDatabase db = PlaceDatabase::Open(PlainDir());
  EXPECT_EQ(StorageView(db).bow_index(), nullptr);
  QueryOptions bow;
  bow.retrieval.method = RetrievalMethod::kBow;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.Query(Features(42), bow); },
                                          "rebuild the database with index set to bow"));
}

// Resident kB of this process's mappings of the file of `dir` whose name
// starts with `prefix` (/proc/self/smaps).
double MappedRssKb(const std::string& dir, const std::string& prefix) {
  std::ifstream in("/proc/self/smaps");
  const std::string path = fs::canonical(dir).string() + "/" + prefix;
  std::string line;
  bool ours = false;
  double kb = 0.0;
  while (std::getline(in, line)) {
    const size_t slash = line.find('/');
    if (!line.empty() && std::isxdigit(static_cast<unsigned char>(line[0])) &&
        line.find('-') != std::string::npos) {
      ours = slash != std::string::npos && line.compare(slash, path.size(), path) == 0;
    } else if (ours && line.rfind("Rss:", 0) == 0) {
      kb += std::stod(line.substr(4));
    }
  }
  return kb;
}

// resident_limit_mb: after a query over the limit, the session's releaser
// lets go of the keyframe file's pages (all of them here: the test
// process's libraries alone are above 1 MiB) and keeps the posting lists;
// the answers are the same. WaitForBackgroundWork is the settled point.
TEST_F(SearchTest, ResidentLimitLetsGoOfTheKeyframeFile) {
  QueryOptions bow;
  bow.retrieval.method = RetrievalMethod::kBow;
  OpenOptions plain;
  plain.prefetch = false;  // only queries map pages
  OpenOptions limited = plain;
  limited.resident_limit_mb = 1;
  std::vector<QueryResult> expected;
  {
    const PlaceDatabase db = PlaceDatabase::Open(Dir(), plain);
    for (int id = 41; id <= 50; ++id) expected.push_back(db.Query(Features(id), bow));
    EXPECT_GT(MappedRssKb(Dir(), "keyframes."), 0.0);  // without a limit the pages stay
  }
  const PlaceDatabase db = PlaceDatabase::Open(Dir(), limited);
  for (int id = 41; id <= 50; ++id) {
    const QueryResult r = db.Query(Features(id), bow);
    const QueryResult& e = expected[static_cast<size_t>(id - 41)];
    ASSERT_EQ(r.ranked.size(), e.ranked.size()) << id;
    for (size_t k = 0; k < r.ranked.size(); ++k) {
      EXPECT_EQ(r.ranked[k].keyframe_id, e.ranked[k].keyframe_id) << id;
      EXPECT_EQ(r.ranked[k].score, e.ranked[k].score) << id;
    }
    db.WaitForBackgroundWork();
    EXPECT_EQ(MappedRssKb(Dir(), "keyframes."), 0.0) << "after query " << id;
    EXPECT_GT(MappedRssKb(Dir(), "bow."), 0.0) << "after query " << id;  // the postings stay
  }
}

// read_features: queries read the features of the keyframes they examine
// from the file instead of mapping them, so the keyframe file's pages never
// count in the process's resident memory; the answers are the same, with
// and without verification, and so is a keyframe's match detail. (The
// whole-image channel, off here, scans the rows it keeps mapped.)
TEST_F(SearchTest, ReadFeaturesAnswerTheSameWithoutMappingTheKeyframes) {
  QueryOptions bow;
  bow.retrieval.method = RetrievalMethod::kBow;
  bow.whole_image_weight = 0.0;
  bow.whole_image_candidates = 0;
  QueryOptions unverified = bow;
  unverified.verify.enabled = false;
  QueryOptions exhaustive;
  exhaustive.whole_image_weight = 0.0;
  exhaustive.whole_image_candidates = 0;
  const std::vector<const QueryOptions*> searches = {&bow, &unverified, &exhaustive};
  OpenOptions plain;
  plain.prefetch = false;  // only queries map pages
  OpenOptions reading = plain;
  reading.read_features = true;
  std::vector<QueryResult> expected;
  std::vector<MatchDetail> details;
  double mapped_growth_kb = 0.0;
  {
    const PlaceDatabase db = PlaceDatabase::Open(Dir(), plain);
    EXPECT_FALSE(StorageView(db).database().reads_features());
    EXPECT_FALSE(db.reads_features());  // a small map: below read_features_above_mb
    // A small file is all resident after the open: start with none of it.
    StorageView(db).database().mapped_file()->ReleaseResidentPages();
    const double opened_kb = MappedRssKb(Dir(), "keyframes.");
    for (int id = 41; id <= 46; ++id)
      for (const QueryOptions* options : searches)
        expected.push_back(db.Query(Features(id), *options));
    mapped_growth_kb = MappedRssKb(Dir(), "keyframes.") - opened_kb;
    details.push_back(db.Explain(Features(41), expected[0].ranked[0].keyframe_id, bow));
  }
  {
    // The map's size decides when read_features does not: in MiB, above.
    OpenOptions by_size = plain;
    by_size.read_features_above_mb = 1;
    const PlaceDatabase sized = PlaceDatabase::Open(Dir(), by_size);
    const uint64_t bytes = StorageView(sized).database().keyframes_bytes();
    EXPECT_EQ(sized.reads_features(), bytes > (uint64_t{1} << 20)) << bytes;
    by_size.read_features_above_mb = 0;
    EXPECT_FALSE(PlaceDatabase::Open(Dir(), by_size).reads_features());
  }
  const PlaceDatabase db = PlaceDatabase::Open(Dir(), reading);
  EXPECT_TRUE(StorageView(db).database().reads_features());
  EXPECT_TRUE(db.reads_features());
  StorageView(db).database().mapped_file()->ReleaseResidentPages();
  const double opened_kb = MappedRssKb(Dir(), "keyframes.");
  size_t at = 0;
  int answered = 0;
  for (int id = 41; id <= 46; ++id) {
    for (const QueryOptions* options : searches) {
      const QueryResult r = db.Query(Features(id), *options);
      const QueryResult& e = expected[at++];
      answered += e.ranked.empty() ? 0 : 1;
      ASSERT_EQ(r.ranked.size(), e.ranked.size()) << id;
      for (size_t k = 0; k < r.ranked.size(); ++k) {
        EXPECT_EQ(r.ranked[k].keyframe_id, e.ranked[k].keyframe_id) << id;
        EXPECT_EQ(r.ranked[k].score, e.ranked[k].score) << id;
        EXPECT_EQ(r.ranked[k].num_inliers, e.ranked[k].num_inliers) << id;
      }
    }
  }
  EXPECT_GE(answered, 12);
  const MatchDetail d = db.Explain(Features(41), expected[0].ranked[0].keyframe_id, bow);
  EXPECT_EQ(d.matches.size(), details[0].matches.size());
  EXPECT_EQ(d.num_inliers, details[0].num_inliers);
  EXPECT_EQ(d.keyframe_stored_points, details[0].keyframe_stored_points);
  const double read_growth_kb = MappedRssKb(Dir(), "keyframes.") - opened_kb;
  std::cerr << "keyframe file resident growth: mapped " << mapped_growth_kb << " kB, read "
            << read_growth_kb << " kB\n";
  EXPECT_GT(mapped_growth_kb, 0.0);
  EXPECT_EQ(read_growth_kb, 0.0);
}

// The background work of a session with prefetch and a resident limit:
// WaitForBackgroundWork returns once the prefetch pass is done and the
// releases asked for are served (after which the keyframe file is let go
// of), and a session closed while both threads may still run stops them
// (the sanitizer passes run this).
TEST_F(SearchTest, BackgroundWorkSettlesAndStops) {
  QueryOptions bow;
  bow.retrieval.method = RetrievalMethod::kBow;
  OpenOptions both;
  both.resident_limit_mb = 1;
  {
    const PlaceDatabase db = PlaceDatabase::Open(Dir(), both);
    db.WaitForBackgroundWork();
    for (int id = 60; id <= 62; ++id) {
      EXPECT_FALSE(db.Query(Features(id), bow).ranked.empty()) << id;
      db.WaitForBackgroundWork();
      EXPECT_EQ(MappedRssKb(Dir(), "keyframes."), 0.0) << "after query " << id;
    }
  }
  for (int i = 0; i < 5; ++i) {
    const PlaceDatabase db = PlaceDatabase::Open(Dir(), both);
    if (i % 2 == 1) db.Query(Features(60 + i), bow);
  }
}

// prefetch (the default) also checks every keyframe's features in the
// background, as their first use would, by reading the keyframe file, not
// mapping it: once the background work is done every keyframe is checked and
// the process maps no more of the file than the open did. Without prefetch
// the queries check what they read.
TEST_F(SearchTest, PrefetchChecksTheFeaturesWithoutMappingThem) {
  {
    const PlaceDatabase db = PlaceDatabase::Open(Dir());
    const double opened_kb = MappedRssKb(Dir(), "keyframes.");
    db.WaitForBackgroundWork();
    const Database& stored = StorageView(db).database();
    for (size_t i = 0; i < stored.size(); ++i) EXPECT_TRUE(stored.FeaturesChecked(i)) << i;
    EXPECT_EQ(MappedRssKb(Dir(), "keyframes."), opened_kb);
  }
  OpenOptions plain;
  plain.prefetch = false;
  const PlaceDatabase db = PlaceDatabase::Open(Dir(), plain);
  db.WaitForBackgroundWork();
  const Database& stored = StorageView(db).database();
  size_t checked = 0;
  for (size_t i = 0; i < stored.size(); ++i) checked += stored.FeaturesChecked(i);
  EXPECT_EQ(checked, 0u);
}

// A subset opened from a bow database rebuilds its index in memory.
TEST_F(SearchTest, SubsetsGetTheirOwnIndex) {
  OpenOptions open;
  open.subset = KeyframeSubset::Partition(1, 2, PartitionScheme::kContiguous);
  const PlaceDatabase part = PlaceDatabase::Open(Dir(), open);
  ASSERT_NE(StorageView(part).bow_index(), nullptr);
  EXPECT_EQ(StorageView(part).bow_index()->size(), part.size());
  QueryOptions bow;
  bow.retrieval.method = RetrievalMethod::kBow;
  bow.retrieval.bow_candidates = 3;
  bow.whole_image_candidates = 0;
  const QueryResult r = part.Query(Features(79), bow);
  EXPECT_EQ(r.num_examined, 3u);
  for (const RankedKeyframe& k : r.ranked) EXPECT_GT(k.keyframe_id, 20);
}

// A bag-of-words search split over partitions in two rounds (shortlists,
// MergeShortlists, each part's share of the candidates, MergeQueryResults)
// answers exactly as the whole database, with and without the whole-image
// channel; the one-round merge of partial bow answers does not always.
TEST_F(SearchTest, PartitionedBowIsExactInTwoRounds) {
  const PlaceDatabase db = PlaceDatabase::Open(Dir());
  for (const PartitionScheme scheme :
       {PartitionScheme::kContiguous, PartitionScheme::kInterleaved}) {
    for (const int num_parts : {2, 4}) {
      std::vector<std::vector<int32_t>> ids(static_cast<size_t>(num_parts));
      const std::vector<int32_t> all = db.keyframe_ids();
      for (size_t i = 0; i < all.size(); ++i) {
        for (int p = 0; p < num_parts; ++p) {
          if (InPartition(i, all.size(), p, num_parts, scheme)) ids[p].push_back(all[i]);
        }
      }
      // The channel off, scoring with candidates, scoring alone.
      for (const int whole_image : {0, 2, 1}) {
        QueryOptions bow;
        bow.retrieval.method = RetrievalMethod::kBow;
        bow.retrieval.bow_candidates = 8;
        bow.retrieval.guided_candidates = 3;
        if (whole_image > 0) {
          bow.whole_image_weight = 5.0;
          bow.whole_image_candidates = whole_image == 2 ? 2 : 0;
        }
        QueryOptions share = bow.ForPartition();
        share.retrieval.method = RetrievalMethod::kExhaustive;
        int one_round_differs = 0;
        for (int id = 41; id <= 84; ++id) {
          const FeatureSet& f = Features(id);
          std::vector<Shortlist> lists;
          for (const auto& part : ids) {
            // Through JSON, as the wire carries it.
            lists.push_back(ShortlistFromJson(ShortlistToJson(db.BowShortlist(f, &part, bow))));
          }
          const std::vector<ShortlistEntry> candidates = MergeShortlists(lists, bow);
          std::vector<QueryResult> answers, one_round;
          for (const auto& part : ids) {
            std::vector<int32_t> mine;
            for (const ShortlistEntry& c : candidates) {
              if (std::count(part.begin(), part.end(), c.keyframe_id) > 0)
                mine.push_back(c.keyframe_id);
            }
            answers.push_back(db.QueryAmong(f, mine, share));
            one_round.push_back(db.QueryAmong(f, part, bow.ForPartition()));
          }
          const QueryResult expected = db.Query(f, bow);
          const QueryResult merged = MergeQueryResults(answers, bow);
          EXPECT_EQ(merged.ranked, expected.ranked)
              << "query " << id << ", " << num_parts << " parts, whole image " << whole_image;
          EXPECT_EQ(merged.matched, expected.matched);
          EXPECT_EQ(merged.num_examined, expected.num_examined);
          one_round_differs += !(MergeQueryResults(one_round, bow).ranked == expected.ranked);
        }
        if (num_parts == 4 && !whole_image) {
          EXPECT_GT(one_round_differs, 0);
        }
      }
    }
  }
  // Bad input: another search method, a keyframe two parts disagree on.
  QueryOptions exhaustive;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { db.BowShortlist(Features(50), nullptr, exhaustive); }, "not of exhaustive"));
  QueryOptions bow;
  bow.retrieval.method = RetrievalMethod::kBow;
  Shortlist a = db.BowShortlist(Features(50), nullptr, bow), b = a;
  ASSERT_FALSE(b.bow.empty());
  b.bow[0].score += 1.0;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] {
        MergeShortlists({a, b}, bow);
      },
      "in two bag-of-words shortlists"));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [] {
        nlohmann::json::parse(R"({"bow": [[1, 2, 0.5]], "whole_image": [],
            "deadline_reached": false, "retrieve_ms": 0})")
            .get<Shortlist>();
      },
      "bow[0] is not [index, keyframe_id, score, guided]"));
}

// Cluster search (time clusters of 5): with the previous answer as prior it
// keeps recall; without a prior it is a global search; a weak local answer
// falls back, and the merged answer is then the whole database's.
TEST_F(SearchTest, ClusterSearchWithPriorAndFallback) {
  OpenOptions open;
  open.clusters.time_keyframes = 5;
  for (const std::string& dir : {PlainDir(), Dir()}) {
    SCOPED_TRACE(dir);
    const PlaceDatabase db = PlaceDatabase::Open(dir, open);
    ASSERT_EQ(StorageView(db).clusters().size(), 8u);
    QueryOptions exhaustive, cluster;
    cluster.retrieval.method = RetrievalMethod::kCluster;
    const double r_exhaustive = RecallAt1(db, exhaustive, false);
    EXPECT_GE(RecallAt1(db, cluster, true), r_exhaustive - 0.02);

    const QueryResult global = db.Query(Features(42), cluster);
    EXPECT_EQ(global.search, "cluster+global");
    EXPECT_EQ(global.cluster, -1);
    // 42 looks like 1..4: a prior there is enough.
    cluster.prior.keyframe_id = 3;
    const QueryResult local = db.Query(Features(42), cluster);
    EXPECT_EQ(local.search, "cluster");
    EXPECT_EQ(local.cluster, 0);
    EXPECT_LE(local.num_examined, 10u);  // clusters 0 and 1
    ASSERT_NE(local.best(), nullptr);
    EXPECT_LE(local.best()->keyframe_id, 10);
    // A prior far away (cluster 4, ids 21..25, 0 hops) is weak: fallback.
    cluster.prior.keyframe_id = 23;
    cluster.retrieval.cluster_hops = 0;
    const QueryResult far = db.Query(Features(42), cluster);
    EXPECT_EQ(far.search, "cluster+fallback");
    if (dir == PlainDir()) {
      EXPECT_EQ(far.num_examined, 40u);
      EXPECT_EQ(far.ranked, db.Query(Features(42), exhaustive).ranked);
    }
    ASSERT_NE(far.best(), nullptr);
    EXPECT_LE(far.best()->keyframe_id, 10);
    // An unknown prior id is no prior.
    cluster.prior.keyframe_id = 999;
    EXPECT_EQ(db.Query(Features(42), cluster).search, "cluster+global");
  }
}

// A deadline too short for anything still examines and verifies the best
// candidate and says how little was covered; a generous one changes nothing.
TEST_F(SearchTest, DeadlineStopsEarlyAndSaysSo) {
  for (const int threads : {1, 2}) {
    OpenOptions open;
    open.threads = threads;
    const PlaceDatabase db = PlaceDatabase::Open(Dir(), open);
    QueryOptions options;
    options.deadline_ms = 1e-6;
    const QueryResult r = db.Query(Features(42), options);
    EXPECT_TRUE(r.deadline_reached);
    EXPECT_GE(r.num_examined, 1u);
    EXPECT_LT(r.num_examined, 40u);
    EXPECT_DOUBLE_EQ(r.coverage, r.num_examined / 40.0);
    EXPECT_GE(r.num_verified, r.ranked.empty() ? 0u : 1u);
    for (const RankedKeyframe& k : r.ranked) EXPECT_TRUE(k.verified());
    options.deadline_ms = 1e6;
    const QueryResult full = db.Query(Features(42), options);
    EXPECT_FALSE(full.deadline_reached);
    EXPECT_EQ(full.ranked, db.Query(Features(42)).ranked);
    EXPECT_DOUBLE_EQ(full.coverage, 1.0);
    // Bag-of-words search: the scoring itself stops at the deadline, and the
    // best candidate found so far is still examined and verified.
    QueryOptions bow;
    bow.retrieval.method = RetrievalMethod::kBow;
    bow.deadline_ms = 1e-6;
    const QueryResult late = db.Query(Features(42), bow);
    EXPECT_TRUE(late.deadline_reached);
    EXPECT_EQ(late.num_examined, 1u);
    bow.deadline_ms = 1e6;
    const QueryResult on_time = db.Query(Features(42), bow);
    EXPECT_FALSE(on_time.deadline_reached);
    bow.deadline_ms = 0.0;
    EXPECT_EQ(on_time.ranked, db.Query(Features(42), bow).ranked);
  }
}

// The retrieve stage leaves the session's estimate of one candidate's cost
// free before the deadline, so that the first candidate, always examined,
// still ends in time: a query reports its costliest candidate; with an
// estimate as long as the whole budget the bag-of-words stage stops at once
// (deadline_reached, though the budget itself is far from spent).
TEST_F(SearchTest, RetrievalLeavesOneCandidatesCostBeforeTheDeadline) {
  const PlaceDatabase db = PlaceDatabase::Open(Dir());
  QueryOptions bow;
  bow.retrieval.method = RetrievalMethod::kBow;
  bow.deadline_ms = 1e6;  // far out of reach, however slow the machine
  const StorageView view(db);
  QueryContext context;
  context.bow = view.bow_index();
  CandidateCost cost;
  context.candidate_cost = &cost;
  const QueryResult first = QueryDatabase(view.database(), Features(42), bow, context);
  EXPECT_FALSE(first.deadline_reached);
  EXPECT_GT(cost.Get(), 0.0);
  EXPECT_LT(cost.Get(), first.times.total_ms);
  cost.Report(1e6);
  const QueryResult squeezed = QueryDatabase(view.database(), Features(42), bow, context);
  EXPECT_TRUE(squeezed.deadline_reached);
  EXPECT_GE(squeezed.num_examined, 1u);
  // Without a session estimate nothing is left free.
  context.candidate_cost = nullptr;
  EXPECT_FALSE(QueryDatabase(view.database(), Features(42), bow, context).deadline_reached);
  // A decaying maximum: a smaller report lowers it by 2 %, a larger one
  // replaces it.
  CandidateCost c;
  EXPECT_EQ(c.Get(), 0.0);
  c.Report(2.0);
  EXPECT_DOUBLE_EQ(c.Get(), 2.0);
  c.Report(1.0);
  EXPECT_DOUBLE_EQ(c.Get(), 1.96);
  c.Report(3.0);
  EXPECT_DOUBLE_EQ(c.Get(), 3.0);
}

// A database of keyframe file format 2 (data/fixtures/rtabmap_v2, made by
// the placedb before format 3) opens, checks every byte on open as before,
// and answers queries 41..84 exactly as that placedb did (its answers are
// in data/fixtures/rtabmap_v2_answers.json). Saved again, it is format 3
// (compact keypoints, quantized to 1/8 px): the answers may move by the
// precision, and recall@1 stays the same.
TEST(FormatVersionTest, ReadsAFormatVersion2DatabaseAndAnswersTheSame) {
  const std::string fixture = PLACEDB_DATA_DIR "/fixtures/rtabmap_v2";
  const nlohmann::json expected =
      nlohmann::json::parse(ReadFileToString(PLACEDB_DATA_DIR "/fixtures/rtabmap_v2_answers.json"));
  testing_util::TempDir tmp;
  const std::string copy = tmp.Path("db");
  fs::copy(fixture, copy);
  // Recall@1 on 41..84 against the ground truth, and how many ranked lists
  // equal the recorded ones.
  const MatchTruth truth = ReadMatchTruth(kTruth);
  auto is_true = [&](int query, int keyframe) {
    const std::vector<int>& ids = truth.at(query);
    return std::binary_search(ids.begin(), ids.end(), keyframe);
  };
  // Lists with the same keyframes in the same order with the same match
  // counts, and the largest difference of an inlier count, over them.
  int same_order = 0, largest_inlier_change = 0;
  auto run = [&](const PlaceDatabase& db, const std::string& search, int* same_lists) {
    QueryOptions options;  // as the answers were recorded: local features alone
    options.whole_image_weight = 0.0;
    options.whole_image_candidates = 0;
    options.retrieval.method =
        search == "bow" ? RetrievalMethod::kBow : RetrievalMethod::kExhaustive;
    const nlohmann::json& recorded = expected["searches"][search]["queries"];
    int correct = 0;
    *same_lists = 0;
    for (int id = 41; id <= 84; ++id) {
      const QueryResult r = db.Query(cv::imread(RtabmapImage(id)), options);
      nlohmann::json ranked = nlohmann::json::array();
      for (const RankedKeyframe& k : r.ranked)
        ranked.push_back({k.keyframe_id, k.num_matches, k.num_inliers});
      const nlohmann::json& before = recorded[std::to_string(id)];
      if (ranked == before) {
        ++*same_lists;
      } else {
        std::printf("query %d (%s): %s, format 2 gave %s\n", id, search.c_str(),
                    ranked.dump().c_str(), before.dump().c_str());
      }
      bool order = ranked.size() == before.size();
      for (size_t i = 0; order && i < ranked.size(); ++i) {
        order = ranked[i][0] == before[i][0] && ranked[i][1] == before[i][1];
        largest_inlier_change = std::max(
            largest_inlier_change, std::abs(ranked[i][2].get<int>() - before[i][2].get<int>()));
      }
      same_order += order;
      if (!r.ranked.empty() && is_true(id, r.ranked[0].keyframe_id)) ++correct;
    }
    return correct;
  };
  const int expected_correct_exhaustive = static_cast<int>(
      std::lround(expected["searches"]["exhaustive"]["recall_at_1"].get<double>() * 44));
  const int expected_correct_bow =
      static_cast<int>(std::lround(expected["searches"]["bow"]["recall_at_1"].get<double>() * 44));
  {
    const PlaceDatabase v2 = PlaceDatabase::Open(copy);
    EXPECT_EQ(StorageView(v2).database().file_format_version(), 2u);
    int same = 0;
    EXPECT_EQ(run(v2, "exhaustive", &same), expected_correct_exhaustive);
    EXPECT_EQ(same, 44);
    EXPECT_EQ(run(v2, "bow", &same), expected_correct_bow);
    EXPECT_EQ(same, 44);
  }
  // Saved again: format 3, same recall; every list has the same keyframes
  // in the same order with the same matches, and the inlier counts RANSAC
  // finds on points moved by at most 1/128 px differ by a few (measured:
  // 9 of the 44 exhaustive lists and 7 of the bow lists, by at most 3).
  same_order = 0;
  largest_inlier_change = 0;
  PlaceDatabase upgraded = PlaceDatabase::Open(copy);
  upgraded.Save();
  const PlaceDatabase v3 = PlaceDatabase::Open(copy);
  EXPECT_EQ(StorageView(v3).database().file_format_version(), 3u);
  int same_exhaustive = 0, same_bow = 0;
  EXPECT_EQ(run(v3, "exhaustive", &same_exhaustive), expected_correct_exhaustive);
  EXPECT_EQ(run(v3, "bow", &same_bow), expected_correct_bow);
  std::printf("format 3: %d of 44 exhaustive and %d of 44 bow ranked lists as format 2's\n",
              same_exhaustive, same_bow);
  EXPECT_EQ(same_order, 88);
  EXPECT_LE(largest_inlier_change, 5);
  EXPECT_GE(same_exhaustive, 30);
  EXPECT_GE(same_bow, 30);
}

}  // namespace
}  // namespace placedb
