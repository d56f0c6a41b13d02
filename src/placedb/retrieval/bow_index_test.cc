#include "placedb/retrieval/bow_index.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "placedb/match/ratio_matcher.h"
#include "placedb/util/file_io.h"
#include "placedb/util/progress.h"
#include "placedb/util/testing.h"
#include "placedb/util/thread_pool.h"

namespace placedb {
namespace {
using testing_util::TempDir;
using testing_util::ThrowsWith;

constexpr int kKeyframes = 40;  // with descriptors; one more has none
constexpr int kRows = 80;       // descriptors per keyframe (and prototypes per set)

// Prototype set j: kRows random ORB descriptors, or 64-float unit vectors.
std::vector<uint8_t> RandomSet(FeatureType type, std::mt19937_64* rng) {
  if (type == FeatureType::kOrb) {
    std::vector<uint8_t> set(kRows * 32);
    for (uint8_t& byte : set) byte = static_cast<uint8_t>((*rng)());
    return set;
  }
  std::normal_distribution<float> normal(0.0f, 1.0f);
  std::vector<float> values(kRows * 64);
  for (int r = 0; r < kRows; ++r) {
    double norm = 0.0;
    for (int d = 0; d < 64; ++d) {
      values[r * 64 + d] = normal(*rng);
      norm += values[r * 64 + d] * values[r * 64 + d];
    }
    for (int d = 0; d < 64; ++d) values[r * 64 + d] /= static_cast<float>(std::sqrt(norm));
  }
  std::vector<uint8_t> set(values.size() * 4);
  std::memcpy(set.data(), values.data(), set.size());
  return set;
}

// Noisy copies of rows [first, first + rows) of a prototype set: ORB with 6
// random bits flipped, SURF with Gaussian noise of 0.03 per coordinate. SURF
// keypoints get a random Laplacian sign, so the database regroups the rows.
FeatureSet NoisyCopy(FeatureType type, const std::vector<uint8_t>& set, int first, int rows,
                     std::mt19937_64* rng) {
  FeatureSet f;
  f.type = type;
  if (type == FeatureType::kOrb) {
    f.descriptors = cv::Mat(rows, 32, CV_8U);
    for (int r = 0; r < rows; ++r) {
      uint8_t* row = f.descriptors.ptr<uint8_t>(r);
      std::memcpy(row, &set[(first + r) * 32], 32);
      for (int flip = 0; flip < 6; ++flip) {
        const int bit = static_cast<int>((*rng)() % 256);
        row[bit / 8] ^= static_cast<uint8_t>(1 << (bit % 8));
      }
    }
  } else {
    std::normal_distribution<float> normal(0.0f, 0.03f);
    f.descriptors = cv::Mat(rows, 64, CV_32F);
    for (int r = 0; r < rows; ++r) {
      const auto* proto = reinterpret_cast<const float*>(&set[(first + r) * 256]);
      for (int d = 0; d < 64; ++d) f.descriptors.at<float>(r, d) = proto[d] + normal(*rng);
    }
  }
  for (int r = 0; r < rows; ++r) {
    cv::KeyPoint kp(static_cast<float>(r), static_cast<float>(2 * r), 7.0f);
    kp.class_id = ((*rng)() % 2 == 0) ? 1 : -1;
    f.keypoints.push_back(kp);
  }
  return f;
}

VocabularyOptions SmallVocabulary(uint64_t seed) {
  VocabularyOptions o;
  o.branching = 8;
  o.depth = 3;
  o.seed = seed;
  return o;
}

std::vector<DescriptorBlock> Blocks(const Database& db) {
  std::vector<DescriptorBlock> blocks;
  for (size_t i = 0; i < db.size(); ++i) blocks.push_back(db.Descriptors(i));
  return blocks;
}

// Keyframe j (id 100 + 3 j, j < kKeyframes) holds noisy copies of prototype
// set j; the last keyframe (id 7) has no features. The vocabulary is trained
// on the database, the index built at direct level 2.
struct World {
  FeatureType type = FeatureType::kOrb;
  std::vector<std::vector<uint8_t>> sets;
  Database db;
  std::shared_ptr<const Vocabulary> vocabulary;
  std::optional<BowIndex> index;
  mutable std::mt19937_64 rng{99};

  // A fresh noisy copy of rows [first, first + rows) of set j, as a query.
  BowVector Query(int j, int first = 0, int rows = kRows) const {
    return Transform(NoisyCopy(type, sets[j], first, rows, &rng));
  }
  BowVector Transform(const FeatureSet& f) const {
    std::vector<int8_t> laplacian;
    return index->Transform(MakeDescriptorBlock(f, &laplacian));
  }
};

World MakeWorld(FeatureType type, int keyframes, const VocabularyOptions& options) {
  World w;
  w.type = type;
  w.db = Database(type, type == FeatureType::kOrb ? 32 : 256);
  std::mt19937_64 rng(2024);
  for (int j = 0; j < keyframes; ++j) {
    w.sets.push_back(RandomSet(type, &rng));
    Keyframe k;
    k.id = 100 + 3 * j;
    w.db.AddKeyframe(k, NoisyCopy(type, w.sets[j], 0, kRows, &rng));
  }
  Keyframe empty;
  empty.id = 7;
  FeatureSet none;
  none.type = type;
  w.db.AddKeyframe(empty, none);
  w.vocabulary = std::make_shared<const Vocabulary>(
      Vocabulary::Train(Blocks(w.db), options, nullptr, nullptr));
  w.index = BowIndex::Build(w.vocabulary, w.db, BowIndexOptions(), nullptr, nullptr);
  return w;
}

const World& Orb() {
  static const World* world =
      new World(MakeWorld(FeatureType::kOrb, kKeyframes, SmallVocabulary(1)));
  return *world;
}

bool Better(const BowIndex::Scored& a, const BowIndex::Scored& b) {
  return a.score > b.score || (a.score == b.score && a.index < b.index);
}

// Query's answer the slow way: BowScore against every keyframe's vector.
std::vector<BowIndex::Scored> BruteForce(const BowIndex& index, const BowVector& query,
                                         size_t max_results, const std::vector<uint32_t>* among) {
  std::vector<BowIndex::Scored> all;
  for (uint32_t i = 0; i < index.size(); ++i) {
    if (among != nullptr && !std::binary_search(among->begin(), among->end(), i)) continue;
    const double score = BowScore(query, index.KeyframeVector(i));
    if (score > 0.0) all.push_back({i, score});
  }
  std::sort(all.begin(), all.end(), Better);
  if (all.size() > max_results) all.resize(max_results);
  return all;
}

void ExpectSameResults(const std::vector<BowIndex::Scored>& got,
                       const std::vector<BowIndex::Scored>& expected) {
  ASSERT_EQ(got.size(), expected.size());
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].index, expected[i].index) << "rank " << i;
    EXPECT_NEAR(got[i].score, expected[i].score, 1e-6) << "rank " << i;
  }
}

void ExpectSameVector(const BowVector& a, const BowVector& b) {
  EXPECT_EQ(a.words, b.words);
  EXPECT_EQ(a.weights, b.weights);
}

// A copy of `db` through `edit` (which may change a keyframe and its
// features), without the keyframes for which `keep` is false.
Database CopyDatabase(
    const Database& db, const std::function<void(size_t, Keyframe*, FeatureSet*)>& edit,
    const std::function<bool(size_t)>& keep = [](size_t) { return true; }) {
  Database copy(db.feature_type(), db.descriptor_bytes());
  for (size_t i = 0; i < db.size(); ++i) {
    if (!keep(i)) continue;
    Keyframe k = db.keyframe(i);
    FeatureSet f;
    f.type = db.feature_type();
    const std::vector<cv::KeyPoint> kp = db.Keypoints(i);
    f.keypoints.assign(kp.begin(), kp.end());
    const DescriptorBlock b = db.Descriptors(i);
    f.descriptors = cv::Mat(b.rows, 32, CV_8U, const_cast<uint8_t*>(b.data)).clone();
    edit(i, &k, &f);
    copy.AddKeyframe(k, f);
  }
  return copy;
}

std::string SavedBytes(const BowIndex& index, const TempDir& dir) {
  const std::string path = dir.Path("bow.bin");
  index.Save(path);
  return ReadFileToString(path);
}

TEST(BowScore, IsDbow2sL1Score) {
  const BowVector a{{1, 2}, {0.5f, 0.5f}};
  const BowVector b{{2, 3}, {0.25f, 0.75f}};
  EXPECT_DOUBLE_EQ(BowScore(a, b), 0.25);
  EXPECT_DOUBLE_EQ(BowScore(b, a), 0.25);
  EXPECT_DOUBLE_EQ(BowScore(a, a), 1.0);
  EXPECT_EQ(BowScore(a, BowVector{{0, 3}, {0.5f, 0.5f}}), 0.0);
  EXPECT_EQ(BowScore(a, BowVector()), 0.0);
  // 1 - 0.5 |a - b|_1 for L1-normalised vectors.
  const BowVector c{{1, 2, 5}, {0.2f, 0.3f, 0.5f}};
  const double l1 = std::abs(0.5 - 0.2) + std::abs(0.5 - 0.3) + 0.5;
  EXPECT_NEAR(BowScore(a, c), 1.0 - 0.5 * l1, 1e-7);
  // Opposite signs share nothing: (|a| + |b| - |a - b|) / 2 = 0.
  EXPECT_EQ(BowScore(a, BowVector{{1}, {-0.5f}}), 0.0);
}

TEST(BowIndexOptions, CheckRejectsOutOfRange) {
  EXPECT_EQ(BowIndexOptions().Check(), "");
  BowIndexOptions o;
  o.direct_level = -1;
  EXPECT_NE(o.Check().find("direct_level"), std::string::npos);
  o.direct_level = 9;
  EXPECT_NE(o.Check().find("direct_level"), std::string::npos);
  o.direct_level = 8;
  EXPECT_EQ(o.Check(), "");
  const World& w = Orb();
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { BowIndex::Build(w.vocabulary, w.db, o, nullptr, nullptr); }, "deeper"));
  o.direct_level = -1;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { BowIndex::Build(w.vocabulary, w.db, o, nullptr, nullptr); }, "direct_level"));
}

TEST(BowIndex, TransformGivesNormalisedSortedVectors) {
  const World& w = Orb();
  const BowIndex& index = *w.index;
  EXPECT_EQ(index.size(), w.db.size());
  EXPECT_EQ(&index.vocabulary(), w.vocabulary.get());
  for (uint32_t i = 0; i < index.size(); ++i) {
    std::vector<uint32_t> nodes;
    const BowVector v = index.Transform(w.db.Descriptors(i), &nodes);
    ExpectSameVector(v, index.KeyframeVector(i));
    EXPECT_EQ(nodes, index.DirectNodes(i));
    ASSERT_EQ(v.words.size(), v.weights.size());
    if (i == kKeyframes) {
      EXPECT_TRUE(v.empty());
      continue;
    }
    double sum = 0.0;
    for (size_t e = 0; e < v.size(); ++e) {
      if (e > 0) {
        EXPECT_LT(v.words[e - 1], v.words[e]);
      }
      EXPECT_GT(v.weights[e], 0.0f);
      sum += v.weights[e];
    }
    EXPECT_NEAR(sum, 1.0, 1e-5);
    EXPECT_NEAR(BowScore(v, v), 1.0, 1e-5);
  }
  FeatureSet surf;
  surf.type = FeatureType::kSurf;
  surf.keypoints.resize(2);
  surf.descriptors = cv::Mat::zeros(2, 64, CV_32F);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { w.Transform(surf); }, "cannot be looked up"));
}

TEST(BowIndex, DirectNodesHaveOneEntryPerFeatureRow) {
  const World& w = Orb();
  const BowIndex& index = *w.index;
  EXPECT_EQ(index.direct_level(), 2);
  for (uint32_t i = 0; i < index.size(); ++i) {
    const std::vector<uint32_t> nodes = index.DirectNodes(i);
    ASSERT_EQ(nodes.size(), w.db.FeatureCount(i));
    const DescriptorBlock block = w.db.Descriptors(i);
    for (int r = 0; r < block.rows; ++r) {
      uint32_t node = 0;
      w.vocabulary->Word(block.Row(r), 2, &node);
      EXPECT_EQ(nodes[r], node);
      EXPECT_EQ(w.vocabulary->node(node).level, 2u);
    }
  }
  EXPECT_TRUE(index.DirectNodes(kKeyframes).empty());
  EXPECT_TRUE(
      ThrowsWith<InvalidArgument>([&] { index.DirectNodes(kKeyframes + 1); }, "keyframe index"));
}

TEST(BowIndex, QueryRanksTheKeyframeOfTheSameSetFirst) {
  const World& w = Orb();
  for (int j = 0; j < kKeyframes; ++j) {
    const std::vector<BowIndex::Scored> best = w.index->Query(w.Query(j, 10, 60), 3);
    ASSERT_EQ(best.size(), 3u);
    EXPECT_EQ(best[0].index, static_cast<uint32_t>(j));
    EXPECT_GT(best[0].score, 0.3);
    EXPECT_GT(best[0].score, 2 * best[1].score);
  }
}

TEST(BowIndex, QueryEqualsBruteForceScores) {
  const World& w = Orb();
  const BowIndex& index = *w.index;
  std::mt19937_64 rng(5);
  std::vector<BowVector> queries;
  for (int t = 0; t < 10; ++t) {
    // Half of one set and half of another.
    const int a = static_cast<int>(rng() % kKeyframes), b = static_cast<int>(rng() % kKeyframes);
    FeatureSet f = NoisyCopy(w.type, w.sets[a], 0, kRows / 2, &rng);
    const FeatureSet g = NoisyCopy(w.type, w.sets[b], kRows / 2, kRows / 2, &rng);
    f.keypoints.insert(f.keypoints.end(), g.keypoints.begin(), g.keypoints.end());
    cv::vconcat(f.descriptors, g.descriptors, f.descriptors);
    queries.push_back(w.Transform(f));
  }
  // Arbitrary vectors too: any words, weights of any sign (<= 0 score nothing).
  for (int t = 0; t < 10; ++t) {
    BowVector v;
    for (uint32_t word = 0; word < w.vocabulary->num_words(); ++word) {
      if (rng() % 4 != 0) continue;
      v.words.push_back(word);
      v.weights.push_back(static_cast<float>(static_cast<int>(rng() % 1000) - 200) / 5000.0f);
    }
    queries.push_back(v);
  }
  for (const BowVector& q : queries) {
    for (const size_t m : {size_t{1}, size_t{3}, size_t{10}, size_t{kKeyframes + 5}}) {
      ExpectSameResults(index.Query(q, m), BruteForce(index, q, m, nullptr));
    }
  }
  EXPECT_TRUE(index.Query(queries[0], 0).empty());
  EXPECT_TRUE(index.Query(BowVector(), 10).empty());
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] {
        index.Query(BowVector{{5, 3}, {0.5f, 0.5f}}, 10);
      },
      "ascending"));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] {
        index.Query(BowVector{{w.vocabulary->num_words()}, {1.0f}}, 10);
      },
      "below"));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] {
        index.Query(BowVector{{1, 2}, {1.0f}}, 10);
      },
      "one weight per word"));
}

// A deadline that has passed stops the scoring once a keyframe has a
// score: the scores are those of the query's first words up to the first
// that has postings; one that does not pass changes nothing.
TEST(BowIndex, QueryStopsAtTheDeadline) {
  const World& w = Orb();
  const BowIndex& index = *w.index;
  const BowVector q = w.Query(3);
  ASSERT_GT(q.words.size(), 20u);
  const Timer clock;
  bool stopped = false;
  const std::vector<BowIndex::Scored> full = index.Query(q, kKeyframes);
  ExpectSameResults(index.Query(q, kKeyframes, nullptr, Deadline(clock, 1e9), &stopped), full);
  EXPECT_FALSE(stopped);
  while (clock.ElapsedMs() < 0.01) {
  }
  const std::vector<BowIndex::Scored> partial =
      index.Query(q, kKeyframes, nullptr, Deadline(clock, 0.001), &stopped);
  EXPECT_TRUE(stopped);
  BowVector prefix;
  for (size_t scored = 1; scored <= q.words.size(); ++scored) {
    prefix.words.assign(q.words.begin(), q.words.begin() + scored);
    prefix.weights.assign(q.weights.begin(), q.weights.begin() + scored);
    if (!BruteForce(index, prefix, kKeyframes, nullptr).empty()) break;
  }
  ASSERT_FALSE(partial.empty());
  EXPECT_LT(prefix.words.size(), q.words.size());
  ExpectSameResults(partial, BruteForce(index, prefix, kKeyframes, nullptr));
}

TEST(BowIndex, QueryAmongOnlyReturnsThose) {
  const World& w = Orb();
  const BowIndex& index = *w.index;
  std::vector<uint32_t> among;
  for (uint32_t i = 1; i < index.size(); i += 3) among.push_back(i);
  for (int j = 0; j < kKeyframes; j += 5) {
    const BowVector q = w.Query(j);
    for (const size_t m : {size_t{1}, size_t{4}, size_t{100}}) {
      const std::vector<BowIndex::Scored> got = index.Query(q, m, &among);
      for (const BowIndex::Scored& s : got)
        EXPECT_TRUE(std::binary_search(among.begin(), among.end(), s.index)) << s.index;
      ExpectSameResults(got, BruteForce(index, q, m, &among));
    }
    const bool listed = std::binary_search(among.begin(), among.end(), uint32_t(j));
    EXPECT_EQ(index.Query(q, 1, &among)[0].index == static_cast<uint32_t>(j), listed);
    // The scratch state of one query does not leak into the next.
    ExpectSameResults(index.Query(q, 100), BruteForce(index, q, 100, nullptr));
  }
  const std::vector<uint32_t> none;
  EXPECT_TRUE(index.Query(w.Query(0), 10, &none).empty());
  const std::vector<uint32_t> unsorted{4, 2};
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { index.Query(w.Query(0), 10, &unsorted); },
                                          "sorted, unique"));
  const std::vector<uint32_t> beyond{1, static_cast<uint32_t>(index.size())};
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { index.Query(w.Query(0), 10, &beyond); }, "below"));
}

TEST(BowIndex, QueryIsThreadSafe) {
  const World& w = Orb();
  std::vector<BowVector> queries;
  std::vector<std::vector<BowIndex::Scored>> expected;
  for (int j = 0; j < kKeyframes; ++j) {
    queries.push_back(w.Query(j));
    expected.push_back(w.index->Query(queries.back(), 5));
  }
  ThreadPool pool(2);
  std::vector<std::vector<BowIndex::Scored>> got(queries.size());
  pool.ParallelFor(queries.size(), [&](size_t i) { got[i] = w.index->Query(queries[i], 5); });
  for (size_t i = 0; i < queries.size(); ++i) ExpectSameResults(got[i], expected[i]);
}

TEST(BowIndex, BuildIsDeterministicForAnyThreadCount) {
  TempDir dir;
  const World& w = Orb();
  ThreadPool pool(2);
  ProgressBar progress("test", 1, /*enabled=*/false);
  const BowIndex threaded =
      BowIndex::Build(w.vocabulary, w.db, BowIndexOptions(), &pool, &progress);
  EXPECT_EQ(progress.done(), w.db.size());
  EXPECT_EQ(SavedBytes(threaded, dir), SavedBytes(*w.index, dir));
  EXPECT_EQ(threaded.checksum(), w.index->checksum());
}

TEST(BowIndex, DirectLevelsFromRootToLeaves) {
  const World& w = Orb();
  for (const int level : {0, 3}) {
    BowIndexOptions o;
    o.direct_level = level;
    const BowIndex index = BowIndex::Build(w.vocabulary, w.db, o, nullptr, nullptr);
    for (uint32_t i = 0; i < index.size(); ++i) {
      for (const uint32_t node : index.DirectNodes(i)) {
        if (level == 0) {
          EXPECT_EQ(node, 0u);
        }
        const Vocabulary::Node& n = w.vocabulary->node(node);
        EXPECT_TRUE(static_cast<int>(n.level) == level ||
                    (n.num_children == 0 && static_cast<int>(n.level) < level));
      }
    }
  }
}

TEST(BowIndex, SaveOpenRoundTrip) {
  TempDir dir;
  const World& w = Orb();
  const std::string path = dir.Path("bow.bin");
  w.index->Save(path);
  const std::string vocabulary_path = dir.Path("vocabulary.bin");
  w.vocabulary->Save(vocabulary_path);
  // The vocabulary, too, comes from its file.
  const auto vocabulary = std::make_shared<const Vocabulary>(Vocabulary::Open(vocabulary_path));
  const BowIndex opened = BowIndex::Open(path, vocabulary, w.db);
  EXPECT_EQ(opened.size(), w.index->size());
  EXPECT_EQ(opened.direct_level(), w.index->direct_level());
  EXPECT_EQ(opened.checksum(), w.index->checksum());
  EXPECT_EQ(opened.file_bytes(), w.index->file_bytes());
  for (uint32_t i = 0; i < opened.size(); ++i) {
    ExpectSameVector(opened.KeyframeVector(i), w.index->KeyframeVector(i));
    EXPECT_EQ(opened.DirectNodes(i), w.index->DirectNodes(i));
  }
  // Copies and moves keep the mapped arrays alive.
  std::optional<BowIndex> copy = opened;
  const BowIndex moved = std::move(*copy);
  copy.reset();
  for (int j = 0; j < kKeyframes; ++j) {
    const BowVector q = w.Query(j);
    const std::vector<BowIndex::Scored> expected = w.index->Query(q, 10);
    for (const BowIndex* index : {&opened, &moved}) {
      const std::vector<BowIndex::Scored> got = index->Query(q, 10);
      ASSERT_EQ(got.size(), expected.size());
      for (size_t r = 0; r < got.size(); ++r) {
        EXPECT_EQ(got[r].index, expected[r].index);
        EXPECT_EQ(got[r].score, expected[r].score);
      }
    }
  }
  EXPECT_EQ(SavedBytes(opened, dir), ReadFileToString(path));
}

TEST(BowIndex, OpenRejectsAnotherVocabularyOrDatabase) {
  TempDir dir;
  const World& w = Orb();
  const std::string path = dir.Path("bow.bin");
  w.index->Save(path);
  const auto other = std::make_shared<const Vocabulary>(
      Vocabulary::Train(Blocks(w.db), SmallVocabulary(2), nullptr, nullptr));
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { BowIndex::Open(path, other, w.db); },
                                          {path, "built with another vocabulary"}));
  const auto same = [](size_t, Keyframe*, FeatureSet*) {};
  const Database renumbered =
      CopyDatabase(w.db, [](size_t i, Keyframe* k, FeatureSet*) { k->id += i == 3 ? 1 : 0; });
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(
      [&] { BowIndex::Open(path, w.vocabulary, renumbered); },
      {path, "built with another database", "keyframe 3 has id 109 in the index but 110"}));
  const Database shorter = CopyDatabase(w.db, same, [](size_t i) { return i != 0; });
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { BowIndex::Open(path, w.vocabulary, shorter); },
                                          {path, "built with another database", "keyframes"}));
  const Database fewer_rows = CopyDatabase(w.db, [](size_t i, Keyframe*, FeatureSet* f) {
    if (i != 5) return;
    f->keypoints.pop_back();
    f->descriptors = f->descriptors.rowRange(0, f->descriptors.rows - 1).clone();
  });
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { BowIndex::Open(path, w.vocabulary, fewer_rows); },
                                          {path, "built with another database", "feature rows"}));
  // The same keyframes: opens.
  EXPECT_EQ(BowIndex::Open(path, w.vocabulary, CopyDatabase(w.db, same)).size(), w.db.size());
  EXPECT_TRUE(ThrowsWith<NotFound>(
      [&] { BowIndex::Open(dir.Path("missing.bin"), w.vocabulary, w.db); }, "missing.bin"));
}

class BowIndexFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    good_ = SavedBytes(*Orb().index, dir_);
    header_ = flat_file::ReadHeader<BowIndexFileHeader>(good_.data());
    keyframes_ = header_.num_keyframes;
    entries_ = header_.num_entries;
    features_ = header_.num_features;
    words_ = Orb().vocabulary->num_words();
    flat_file::Layout layout(UINT64_MAX);
    layout.Add(keyframes_, 4);
    vector_offsets_ = layout.Add(keyframes_ + 1, 8);
    direct_offsets_ = layout.Add(keyframes_ + 1, 8);
    byte_offsets_ = layout.Add(keyframes_ + 1, 8);
    totals_ = layout.Add(keyframes_, 8);
    keyframe_bytes_ = layout.Add(header_.keyframe_bytes, 1);
    word_offsets_ = layout.Add(words_ + 1, 8);
    word_byte_offsets_ = layout.Add(words_ + 1, 8);
    postings_ = layout.Add(header_.posting_bytes, 1);
    keyframe_blocks_ = layout.Add(keyframes_, 8);
    word_blocks_ = layout.Add(words_, 8);
    ASSERT_EQ(layout.end(), good_.size());
    ASSERT_EQ(header_.direct_node_bytes, 1u);  // 64 nodes at level 2
  }

  ::testing::AssertionResult Rejects(const std::string& bytes, const std::string& what) {
    const std::string path = dir_.Write("damaged.bin", bytes);
    // Opened, and every byte checked (blocks are checked on first use).
    return ThrowsWith<CorruptDatabase>(
        [&] { BowIndex::Open(path, Orb().vocabulary, Orb().db).VerifyAll(); }, {path, what});
  }
  // `good_` with a value written at `offset`, or its header changed by
  // `edit`, resealed.
  template <typename T>
  std::string With(uint64_t offset, T value) const {
    std::string bytes = good_;
    std::memcpy(&bytes[offset], &value, sizeof(T));
    ResealBowIndex(&bytes);
    return bytes;
  }
  // The header edited (and nothing recomputed but the flat-file checksums).
  template <typename Edit>
  std::string WithHeader(Edit edit) const {
    auto header = flat_file::ReadHeader<BowIndexFileHeader>(good_.data());
    edit(header);
    return flat_file::Patched(good_, 0, header);
  }
  // The value at `offset` of `good_`.
  template <typename T>
  T At(uint64_t offset) const {
    T value;
    std::memcpy(&value, good_.data() + offset, sizeof(T));
    return value;
  }
  uint64_t WordOffset(uint32_t word) const { return At<uint64_t>(word_offsets_ + 8 * word); }
  uint64_t WordByte(uint32_t word) const { return At<uint64_t>(word_byte_offsets_ + 8 * word); }
  uint64_t KeyframeByte(uint32_t i) const { return At<uint64_t>(byte_offsets_ + 8 * i); }
  // A word with at least two postings.
  uint32_t WordWithPostings() const {
    uint32_t word = 0;
    while (WordOffset(word + 1) - WordOffset(word) < 2) ++word;
    return word;
  }

  TempDir dir_;
  std::string good_;
  BowIndexFileHeader header_{};
  uint32_t keyframes_ = 0, words_ = 0;
  uint64_t entries_ = 0, features_ = 0;
  uint64_t vector_offsets_ = 0, direct_offsets_ = 0, byte_offsets_ = 0, totals_ = 0,
           keyframe_bytes_ = 0, word_offsets_ = 0, word_byte_offsets_ = 0, postings_ = 0,
           keyframe_blocks_ = 0, word_blocks_ = 0;
};

TEST_F(BowIndexFileTest, OpenRejectsTruncatedAndFlippedFiles) {
  for (size_t size = 0; size < good_.size(); size += size < 300 ? 1 : 97)
    ASSERT_TRUE(Rejects(good_.substr(0, size), "truncated")) << size;
  EXPECT_TRUE(Rejects(good_ + "x", "trailing bytes"));
  // Every header byte, and bytes spread over every section.
  for (size_t i = 0; i < good_.size(); i += i < 256 ? 1 : 61) {
    std::string bytes = good_;
    bytes[i] = static_cast<char>(bytes[i] ^ (1 << (i % 8)));
    ASSERT_TRUE(Rejects(bytes, "")) << "byte " << i;
  }
  std::string magic = good_;
  magic[0] = 'Q';
  EXPECT_TRUE(Rejects(magic, "not a placedb bag-of-words index file (wrong magic)"));
  EXPECT_TRUE(Rejects(WithHeader([](BowIndexFileHeader& h) { h.common.version = 7; }),
                      "format version 7 is not supported"));
}

TEST_F(BowIndexFileTest, OpenRejectsBadHeaderFields) {
  using H = BowIndexFileHeader;
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { h.vocabulary_checksum = 12345; }),
                      "built with another vocabulary"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { ++h.num_keyframes; }), "built with another database"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { h.direct_level = 4; }), "deeper"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { ++h.num_words; }), "words"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { h.direct_node_bytes = 2; }), "direct entries of 2"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { h.reserved[2] = 1; }), "reserved"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { ++h.tables_checksum; }), "tables checksum mismatch"));
  // One more byte or entry: the sections' padding may absorb it (then the
  // offsets disagree), or the size does not match.
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { ++h.num_entries; }), ""));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { ++h.keyframe_bytes; }), ""));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { ++h.posting_bytes; }), ""));
  EXPECT_TRUE(
      Rejects(WithHeader([](H& h) { h.posting_bytes = UINT64_MAX / 2; }), "does not match"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { --h.num_features; }), ""));
}

TEST_F(BowIndexFileTest, OpenRejectsBadSections) {
  // Tables.
  EXPECT_TRUE(Rejects(With<uint64_t>(vector_offsets_, 1), "vector offsets"));
  EXPECT_TRUE(
      Rejects(With<uint64_t>(vector_offsets_ + 8, entries_ + 1), "vector offsets decrease"));
  EXPECT_TRUE(Rejects(With<uint64_t>(byte_offsets_ + 8, header_.keyframe_bytes + 1),
                      "keyframe byte offsets decrease"));
  EXPECT_TRUE(Rejects(With<uint64_t>(word_byte_offsets_ + 8, header_.posting_bytes + 1),
                      "word byte offsets decrease"));
  EXPECT_TRUE(Rejects(With<double>(totals_, std::numeric_limits<double>::quiet_NaN()),
                      "keyframe 0 has total nan"));
  EXPECT_TRUE(Rejects(With<double>(totals_, -1.0), "keyframe 0 has total -1"));
  EXPECT_TRUE(Rejects(With<double>(totals_, At<double>(totals_) * 0.5), "is not its words'"));
  EXPECT_TRUE(Rejects(With<double>(totals_ + 8 * kKeyframes, 1.0), "has total 1"));  // empty
  // Keyframe vectors: a count flag set moves every entry after it.
  const uint64_t first_entry = keyframe_bytes_ + KeyframeByte(0);
  EXPECT_TRUE(Rejects(With<uint8_t>(first_entry, At<uint8_t>(first_entry) ^ 1), "keyframe 0"));
  // A first word beyond the vocabulary (the varint of (W << 1), then the rest).
  EXPECT_TRUE(Rejects(With<uint8_t>(first_entry, 0xff), "keyframe 0"));
  // Direct entries: the last byte of keyframe 0's block.
  const uint64_t last_direct = keyframe_bytes_ + KeyframeByte(1) - 1;
  EXPECT_TRUE(Rejects(With<uint8_t>(last_direct, 200), "(rank 200) is not a node of level 2"));
  // Inverted file.
  const uint32_t word = WordWithPostings();
  const uint64_t first = postings_ + WordByte(word);
  ASSERT_EQ(At<uint8_t>(first), 1);  // the width: 1 byte a code
  EXPECT_TRUE(Rejects(With<uint8_t>(first, 9), "a width of 9 bytes"));
  EXPECT_TRUE(Rejects(With<uint8_t>(first, 2), "the postings of word " + std::to_string(word)));
  EXPECT_TRUE(Rejects(With<uint8_t>(first + 1, static_cast<uint8_t>(2 * keyframes_)),
                      "a keyframe is not ascending and below"));
  // A posting moved to the next keyframe: the transposition breaks.
  uint8_t code = At<uint8_t>(first + 1);
  ASSERT_LT(code, 0x7e);
  EXPECT_TRUE(Rejects(With<uint8_t>(first + 1, static_cast<uint8_t>(code + 1)),
                      "disagrees with the keyframe vectors"));
  // Weights: impossible ones, and one that is not its vector's.
  const uint64_t weights = first + 1 + (WordOffset(word + 1) - WordOffset(word));
  EXPECT_TRUE(Rejects(With<float>(weights, 0.0f), "a weight of 0 (finite and > 0 expected)"));
  EXPECT_TRUE(Rejects(With<float>(weights, std::numeric_limits<float>::quiet_NaN()),
                      "(finite and > 0 expected)"));
  EXPECT_TRUE(Rejects(With<float>(weights, At<float>(weights) * 0.5f),
                      "disagrees with the keyframe vectors"));
  // A posting moved to the next word: the bytes no longer fill the blocks.
  EXPECT_TRUE(Rejects(With<uint64_t>(word_offsets_ + 8 * (word + 1), WordOffset(word + 1) - 1),
                      "the postings of word"));
  EXPECT_TRUE(Rejects(With<uint64_t>(word_offsets_ + 8 * (word + 1), entries_ + 1),
                      "word offsets decrease"));
}

TEST_F(BowIndexFileTest, ResealedRandomDamageIsCaught) {
  // Every byte of the index but the direct entries is checked against the
  // others, the vocabulary or the database, and padding must be 0, so no
  // resealed bit flip there opens (a changed entry breaks its total, its
  // block's length or the transposition). A direct entry may turn into
  // another node of its level.
  std::vector<bool> direct(good_.size(), false);
  for (uint32_t i = 0; i < keyframes_; ++i) {
    const uint64_t rows =
        At<uint64_t>(direct_offsets_ + 8 * (i + 1)) - At<uint64_t>(direct_offsets_ + 8 * i);
    for (uint64_t b = keyframe_bytes_ + KeyframeByte(i + 1) - rows;
         b < keyframe_bytes_ + KeyframeByte(i + 1); ++b)
      direct[b] = true;
  }
  std::mt19937_64 rng(9);
  int tried = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const uint64_t at = flat_file::kHeaderBytes + rng() % (good_.size() - flat_file::kHeaderBytes);
    if (direct[at]) continue;
    if (at >= keyframe_blocks_) continue;  // the block checksums: resealing recomputes them
    std::string bytes = good_;
    bytes[at] = static_cast<char>(bytes[at] ^ (1 << (rng() % 8)));
    ResealBowIndex(&bytes);
    ASSERT_TRUE(Rejects(bytes, "")) << "byte " << at;
    ++tried;
  }
  EXPECT_GT(tried, 200);
  EXPECT_TRUE(Rejects(With<char>(vector_offsets_ - 1, 1), "padding"));
}

// The blocks are not read on open; each is checked the first time it is
// read: damage there does not stop the open, but reaches no answer.
TEST_F(BowIndexFileTest, BlocksAreCheckedOnFirstUse) {
  const uint32_t word = WordWithPostings();
  std::string bytes = good_;
  bytes[postings_ + WordByte(word) + 1] ^= 0x02;  // a keyframe; not resealed
  const std::string path = dir_.Write("lazy.bin", bytes);
  const BowIndex index = BowIndex::Open(path, Orb().vocabulary, Orb().db);
  EXPECT_EQ(index.format_version(), kBowIndexFormatVersion);
  BowVector other;
  other.words = {word == 0 ? 1u : 0u};
  other.weights = {1.0f};
  EXPECT_NO_THROW(index.Query(other, 5));
  BowVector damaged;
  damaged.words = {word};
  damaged.weights = {1.0f};
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(
      [&] { index.Query(damaged, 5); },
      {path, "the postings of word " + std::to_string(word), "fail their block checksum"}));
  EXPECT_NO_THROW(index.KeyframeVector(0));
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { index.VerifyAll(); }, "payload checksum mismatch"));
  // A keyframe's direct entries.
  bytes = good_;
  bytes[keyframe_bytes_ + KeyframeByte(1) - 2] ^= 0x01;
  const std::string path2 = dir_.Write("lazy2.bin", bytes);
  const BowIndex index2 = BowIndex::Open(path2, Orb().vocabulary, Orb().db);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { index2.DirectNodes(0); },
                                          "keyframe 0's entries fail their block checksum"));
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { index2.KeyframeVector(0); },
                                          "keyframe 0's entries fail their block checksum"));
  EXPECT_NO_THROW(index2.DirectNodes(1));
  // Undamaged: VerifyAll passes.
  EXPECT_NO_THROW(
      BowIndex::Open(dir_.Write("good.bin", good_), Orb().vocabulary, Orb().db).VerifyAll());
}

// The background check (what a session's prefetch thread runs) checks every
// word's postings while queries run, and leaves a damaged one unchecked: the
// query that reads it still reports it, as without the check.
TEST_F(BowIndexFileTest, BackgroundCheckLeavesDamageToTheQuery) {
  const uint32_t word = WordWithPostings();
  std::string bytes = good_;
  bytes[postings_ + WordByte(word) + 1] ^= 0x02;  // a keyframe; not resealed
  const std::string path = dir_.Write("background.bin", bytes);
  const BowIndex index = BowIndex::Open(path, Orb().vocabulary, Orb().db);
  BowVector damaged;
  damaged.words = {word};
  damaged.weights = {1.0f};
  const std::atomic<bool> stop{false};
  std::thread checker([&] { index.CheckInBackground(stop); });
  // Queries of other words meanwhile, on this thread.
  for (uint32_t w = 0; w < 50; ++w) {
    if (w == word) continue;
    BowVector other;
    other.words = {w};
    other.weights = {1.0f};
    EXPECT_NO_THROW(index.Query(other, 5)) << w;
  }
  checker.join();
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(
      [&] { index.Query(damaged, 5); },
      {path, "the postings of word " + std::to_string(word), "fail their block checksum"}));
  // An undamaged index checked in the background answers as one checked
  // by its queries; a stopped check checks nothing.
  const BowIndex good = BowIndex::Open(dir_.Write("good.bin", good_), Orb().vocabulary, Orb().db);
  good.CheckInBackground(stop);
  const BowIndex fresh = BowIndex::Open(dir_.Path("good.bin"), Orb().vocabulary, Orb().db);
  for (size_t k = 0; k < Orb().db.size(); k += 7) {
    const BowVector q = fresh.KeyframeVector(static_cast<uint32_t>(k));
    const auto a = good.Query(q, 5), b = fresh.Query(q, 5);
    ASSERT_EQ(a.size(), b.size());
    for (size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a[i].index, b[i].index);
      EXPECT_EQ(a[i].score, b[i].score);
    }
  }
  const std::atomic<bool> stopped{true};
  const BowIndex halted = BowIndex::Open(path, Orb().vocabulary, Orb().db);
  halted.CheckInBackground(stopped);
  EXPECT_TRUE(
      ThrowsWith<CorruptDatabase>([&] { halted.Query(damaged, 5); }, "fail their block checksum"));
  // A keyframe's block (vector and direct entries) damaged: the background
  // check leaves it to the query too, and checks the others.
  std::string keyframe_damaged = good_;
  keyframe_damaged[keyframe_bytes_ + KeyframeByte(2) - 2] ^= 0x01;  // keyframe 1's
  const BowIndex index3 =
      BowIndex::Open(dir_.Write("background3.bin", keyframe_damaged), Orb().vocabulary, Orb().db);
  index3.CheckInBackground(stop);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { index3.DirectNodes(1); },
                                          "keyframe 1's entries fail their block checksum"));
  EXPECT_TRUE(index3.KeyframeChecked(0));
  EXPECT_TRUE(index3.KeyframeChecked(2));
  EXPECT_FALSE(index3.KeyframeChecked(1));
}

// A version 2 file (f32 arrays), written here as the placedb of that
// version wrote it: its header is checked and the index rebuilt, which
// answers as the version 3 index does; the compact file is a fraction of
// its size.
TEST(BowIndex, VersionTwoFilesAreRebuiltTheSame) {
  TempDir dir;
  const World& w = Orb();
  const BowIndex& index = *w.index;
  const uint32_t K = static_cast<uint32_t>(index.size()), W = w.vocabulary->num_words();
  std::vector<BowVector> vectors;
  std::vector<std::vector<uint32_t>> nodes;
  uint64_t P = 0, F = 0;
  for (uint32_t i = 0; i < K; ++i) {
    vectors.push_back(index.KeyframeVector(i));
    nodes.push_back(index.DirectNodes(i));
    P += vectors.back().size();
    F += nodes.back().size();
  }
  flat_file::Layout layout(UINT64_MAX);
  const uint64_t ids = layout.Add(K, 4), vector_offsets = layout.Add(K + 1, 8),
                 vector_words = layout.Add(P, 4), vector_weights = layout.Add(P, 4),
                 direct_offsets = layout.Add(K + 1, 8), direct_nodes = layout.Add(F, 4),
                 word_offsets = layout.Add(W + 1, 8), postings = layout.Add(P, 8);
  layout.Add(K, 8);
  layout.Add(W, 8);
  std::string bytes(layout.end(), '\0');
  const auto put = [&](uint64_t at, const auto& value) {
    std::memcpy(&bytes[at], &value, sizeof(value));
  };
  std::vector<std::vector<std::pair<uint32_t, float>>> lists(W);
  uint64_t e = 0, f = 0;
  for (uint32_t i = 0; i < K; ++i) {
    put(ids + 4 * i, w.db.keyframe(i).id);
    put(vector_offsets + 8 * i, e);
    put(direct_offsets + 8 * i, f);
    for (size_t j = 0; j < vectors[i].size(); ++j, ++e) {
      put(vector_words + 4 * e, vectors[i].words[j]);
      put(vector_weights + 4 * e, vectors[i].weights[j]);
      lists[vectors[i].words[j]].push_back({i, vectors[i].weights[j]});
    }
    for (const uint32_t node : nodes[i]) put(direct_nodes + 4 * f++, node);
  }
  put(vector_offsets + 8 * K, e);
  put(direct_offsets + 8 * K, f);
  e = 0;
  for (uint32_t word = 0; word < W; ++word) {
    put(word_offsets + 8 * word, e);
    for (const auto& [k, weight] : lists[word]) {
      put(postings + 8 * e, k);
      put(postings + 8 * e + 4, weight);
      ++e;
    }
  }
  put(word_offsets + 8 * W, e);
  BowIndexFileHeader header{};
  header.vocabulary_checksum = w.vocabulary->checksum();
  header.num_keyframes = K;
  header.direct_level = 2;
  header.num_words = W;
  header.num_entries = P;
  header.num_features = F;
  header.tables_checksum = 1;  // not read
  std::memcpy(&bytes[0], &header, sizeof(header));
  flat_file::Seal(&bytes[0], bytes.size(), kBowIndexMagic, 2);
  const BowIndex v2 = BowIndex::Open(dir.Write("v2.bin", bytes), w.vocabulary, w.db);
  EXPECT_EQ(v2.format_version(), kBowIndexFormatVersion);
  EXPECT_EQ(v2.checksum(), index.checksum());
  std::printf("version 2: %zu bytes, version 3: %llu bytes\n", bytes.size(),
              static_cast<unsigned long long>(index.file_bytes()));
  EXPECT_LT(index.file_bytes(), bytes.size());
  for (int j = 0; j < kKeyframes; ++j) {
    const BowVector q = w.Query(j);
    ExpectSameResults(v2.Query(q, 10), index.Query(q, 10));
  }
  // Its header is still checked.
  header.direct_node_bytes = 1;
  std::memcpy(&bytes[0], &header, sizeof(header));
  flat_file::Seal(&bytes[0], bytes.size(), kBowIndexMagic, 2);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(
      [&] { BowIndex::Open(dir.Write("v2b.bin", bytes), w.vocabulary, w.db); }, "reserved"));
  const auto other = std::make_shared<const Vocabulary>(
      Vocabulary::Train(Blocks(w.db), SmallVocabulary(2), nullptr, nullptr));
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { BowIndex::Open(dir.Path("v2.bin"), other, w.db); },
                                          "built with another vocabulary"));
}

TEST(BowIndex, SurfIndex) {
  VocabularyOptions o;
  o.branching = 6;
  o.depth = 2;
  const World w = MakeWorld(FeatureType::kSurf, 12, o);
  const BowIndex& index = *w.index;
  for (int j = 0; j < 12; ++j) {
    const BowVector q = w.Query(j);
    const std::vector<BowIndex::Scored> best = index.Query(q, 2);
    ASSERT_FALSE(best.empty());
    EXPECT_EQ(best[0].index, static_cast<uint32_t>(j));
    ExpectSameResults(index.Query(q, 20), BruteForce(index, q, 20, nullptr));
  }
  // The direct index follows the database's rows (regrouped by Laplacian sign).
  for (uint32_t i = 0; i < index.size(); ++i) {
    const DescriptorBlock block = w.db.Descriptors(i);
    ASSERT_EQ(index.DirectNodes(i).size(), static_cast<size_t>(block.rows));
    for (int r = 0; r < block.rows; ++r) {
      uint32_t node = 0;
      w.vocabulary->Word(block.Row(r), 2, &node);
      EXPECT_EQ(index.DirectNodes(i)[r], node);
    }
  }
  const World& orb = Orb();
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { BowIndex::Build(w.vocabulary, orb.db, BowIndexOptions(), nullptr, nullptr); },
      "the database holds orb descriptors"));
}

}  // namespace
}  // namespace placedb
