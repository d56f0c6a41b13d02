#include "placedb/retrieval/vocabulary.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "placedb/match/hamming.h"
#include "placedb/match/l2_distance.h"
#include "placedb/util/file_io.h"
#include "placedb/util/progress.h"
#include "placedb/util/testing.h"
#include "placedb/util/thread_pool.h"

namespace placedb {
namespace {
using testing_util::TempDir;
using testing_util::ThrowsWith;

// Descriptor rows that are noisy copies of random prototypes, shuffled and
// cut into blocks (the documents of the IDF).
struct Synthetic {
  FeatureType type = FeatureType::kOrb;
  int row_bytes = 32;
  std::vector<uint8_t> data;   // the rows, back to back
  std::vector<int> prototype;  // of each row
  int rows_per_block = 50;

  size_t rows() const { return prototype.size(); }
  const uint8_t* Row(size_t i) const { return data.data() + i * row_bytes; }
  std::vector<DescriptorBlock> Blocks() const {
    std::vector<DescriptorBlock> blocks;
    for (size_t begin = 0; begin < rows(); begin += rows_per_block) {
      DescriptorBlock b;
      b.type = type;
      b.row_bytes = row_bytes;
      b.data = Row(begin);
      b.rows = static_cast<int>(std::min<size_t>(rows_per_block, rows() - begin));
      blocks.push_back(b);
    }
    return blocks;
  }
};

// Rows in shuffled order: row r is a copy of prototype order[r] % prototypes.
std::vector<int> ShuffledPrototypes(int prototypes, int copies, std::mt19937_64* rng) {
  std::vector<int> order(static_cast<size_t>(prototypes) * copies);
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i % prototypes);
  std::shuffle(order.begin(), order.end(), *rng);
  return order;
}

// ORB-like rows: random 256-bit prototypes, each copy with `flips` random
// bits flipped.
Synthetic MakeOrb(int prototypes, int copies, int flips, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<uint8_t> protos(static_cast<size_t>(prototypes) * 32);
  for (uint8_t& byte : protos) byte = static_cast<uint8_t>(rng());
  Synthetic s;
  s.prototype = ShuffledPrototypes(prototypes, copies, &rng);
  for (const int p : s.prototype) {
    uint8_t row[32];
    std::memcpy(row, &protos[p * 32], 32);
    for (int f = 0; f < flips; ++f) {
      const int bit = static_cast<int>(rng() % 256);
      row[bit / 8] ^= static_cast<uint8_t>(1 << (bit % 8));
    }
    s.data.insert(s.data.end(), row, row + 32);
  }
  return s;
}

// SURF-like rows: random unit prototypes in 64 dimensions, each copy with
// Gaussian noise of `sigma` per coordinate.
Synthetic MakeSurf(int prototypes, int copies, double sigma, uint64_t seed) {
  constexpr int kDims = 64;
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  std::vector<float> protos(static_cast<size_t>(prototypes) * kDims);
  for (int p = 0; p < prototypes; ++p) {
    double norm = 0.0;
    for (int d = 0; d < kDims; ++d) {
      protos[p * kDims + d] = normal(rng);
      norm += protos[p * kDims + d] * protos[p * kDims + d];
    }
    for (int d = 0; d < kDims; ++d) protos[p * kDims + d] /= static_cast<float>(std::sqrt(norm));
  }
  Synthetic s;
  s.type = FeatureType::kSurf;
  s.row_bytes = kDims * 4;
  s.prototype = ShuffledPrototypes(prototypes, copies, &rng);
  for (const int p : s.prototype) {
    float row[kDims];
    for (int d = 0; d < kDims; ++d)
      row[d] = protos[p * kDims + d] + static_cast<float>(sigma) * normal(rng);
    const auto* bytes = reinterpret_cast<const uint8_t*>(row);
    s.data.insert(s.data.end(), bytes, bytes + sizeof(row));
  }
  return s;
}

VocabularyOptions Options(int branching, int depth, uint64_t seed = 1) {
  VocabularyOptions o;
  o.branching = branching;
  o.depth = depth;
  o.seed = seed;
  return o;
}

std::string SavedBytes(const Vocabulary& v, const TempDir& dir) {
  const std::string path = dir.Path("vocabulary.bin");
  v.Save(path);
  return ReadFileToString(path);
}

std::string CentroidBytes(const Vocabulary& v) {
  std::string out;
  for (uint32_t i = 0; i < v.num_nodes(); ++i)
    out.append(reinterpret_cast<const char*>(v.Centroid(i)), v.row_bytes());
  return out;
}

// The word of `row` found the slow way: at each node, the child at the
// smallest reference distance (ties: the lower child). `node_at` receives the
// node passed at `level` (or the leaf above it).
uint32_t BruteForceWord(const Vocabulary& v, const uint8_t* row, int level, uint32_t* node_at) {
  uint32_t current = 0;
  *node_at = 0;
  for (int l = 0;; ++l) {
    if (l <= level) *node_at = current;
    const Vocabulary::Node& n = v.node(current);
    if (n.num_children == 0) return n.word;
    double best = std::numeric_limits<double>::infinity();
    uint32_t best_child = n.first_child;
    for (uint32_t c = n.first_child; c < n.first_child + n.num_children; ++c) {
      const double d = v.type() == FeatureType::kOrb
                           ? HammingReference(row, v.Centroid(c), v.row_bytes())
                           : L2SquaredReference(reinterpret_cast<const float*>(row),
                                                reinterpret_cast<const float*>(v.Centroid(c)),
                                                v.row_bytes() / 4);
      if (d < best) {
        best = d;
        best_child = c;
      }
    }
    current = best_child;
  }
}

// Trains a 25-word vocabulary (branching 5, depth 2) on `s` and checks that
// each prototype's rows land mostly in one word: at least half of them in
// its most common word, and 95% on average. A prototype whose rows a node
// had to split (more clusters than prototypes under it) falls to about one
// half; most must stay whole.
void ExpectCopiesShareAWord(const Synthetic& s, int prototypes) {
  const Vocabulary v = Vocabulary::Train(s.Blocks(), Options(5, 2), nullptr, nullptr);
  EXPECT_EQ(v.type(), s.type);
  EXPECT_EQ(v.row_bytes(), s.row_bytes);
  EXPECT_GE(v.num_words(), 15u);
  std::vector<std::map<uint32_t, int>> words(prototypes);
  for (size_t r = 0; r < s.rows(); ++r) ++words[s.prototype[r]][v.Word(s.Row(r))];
  double sum = 0.0;
  for (int p = 0; p < prototypes; ++p) {
    int best = 0, total = 0;
    for (const auto& [word, count] : words[p]) {
      best = std::max(best, count);
      total += count;
    }
    const double purity = static_cast<double>(best) / total;
    EXPECT_GE(purity, 0.5) << "prototype " << p;
    sum += purity;
  }
  EXPECT_GE(sum / prototypes, 0.95);
}

TEST(VocabularyOptions, CheckRejectsOutOfRange) {
  EXPECT_EQ(VocabularyOptions().Check(), "");
  EXPECT_EQ(Options(2, 8).Check(), "");
  EXPECT_EQ(Options(64, 4).Check(), "");  // 2^24 words exactly
  auto reason = [](auto change) {
    VocabularyOptions o;
    change(o);
    return o.Check();
  };
  EXPECT_NE(reason([](VocabularyOptions& o) { o.branching = 1; }).find("branching"),
            std::string::npos);
  EXPECT_NE(reason([](VocabularyOptions& o) { o.branching = 65; }).find("branching"),
            std::string::npos);
  EXPECT_NE(reason([](VocabularyOptions& o) { o.depth = 0; }).find("depth"), std::string::npos);
  EXPECT_NE(reason([](VocabularyOptions& o) { o.depth = 9; }).find("depth"), std::string::npos);
  EXPECT_NE(Options(64, 5).Check().find("2^24"), std::string::npos);
  EXPECT_NE(Options(9, 8).Check().find("2^24"), std::string::npos);
  EXPECT_NE(reason([](VocabularyOptions& o) { o.iterations = 0; }).find("iterations"),
            std::string::npos);
  EXPECT_NE(reason([](VocabularyOptions& o) { o.iterations = 101; }).find("iterations"),
            std::string::npos);
  EXPECT_NE(reason([](VocabularyOptions& o) {
              o.max_training_descriptors = 999;
            }).find("vocabulary_sample"),
            std::string::npos);
  EXPECT_NE(reason([](VocabularyOptions& o) {
              o.max_training_descriptors = 100000001;
            }).find("vocabulary_sample"),
            std::string::npos);
  const Synthetic s = MakeOrb(5, 10, 4, 1);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { Vocabulary::Train(s.Blocks(), Options(1, 2), nullptr, nullptr); }, "branching"));
}

TEST(Vocabulary, TrainRejectsBadInput) {
  const Synthetic orb = MakeOrb(5, 10, 4, 1);
  const Synthetic surf = MakeSurf(5, 10, 0.01, 1);
  const VocabularyOptions o = Options(4, 2);
  auto train = [&](const std::vector<DescriptorBlock>& blocks) {
    return [&, blocks] { Vocabulary::Train(blocks, o, nullptr, nullptr); };
  };
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(train({}), "no descriptor blocks"));
  DescriptorBlock empty;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(train({empty, empty}), "no descriptor rows"));
  std::vector<DescriptorBlock> mixed = orb.Blocks();
  mixed.push_back(surf.Blocks()[0]);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(train(mixed), "block 1 holds surf rows"));
  std::vector<DescriptorBlock> narrow = orb.Blocks();
  narrow[0].row_bytes = 16;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(train(narrow), "16 bytes"));
  Synthetic nan = surf;
  const float bad = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(nan.data.data() + 12, &bad, sizeof(bad));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(train(nan.Blocks()), "not finite"));
}

TEST(Vocabulary, TrainingIsDeterministicForAnyThreadCount) {
  TempDir dir;
  ThreadPool one(1), two(2);
  // 6000 rows sampled down to 5000: the sample, several row chunks at the
  // root and sibling nodes in parallel are all exercised.
  for (const Synthetic& s : {MakeOrb(50, 120, 8, 7), MakeSurf(50, 120, 0.05, 7)}) {
    SCOPED_TRACE(FeatureTypeName(s.type));
    VocabularyOptions o = Options(6, 3, 3);
    o.max_training_descriptors = 5000;
    const std::vector<DescriptorBlock> blocks = s.Blocks();
    const Vocabulary alone = Vocabulary::Train(blocks, o, nullptr, nullptr);
    const std::string bytes = SavedBytes(alone, dir);
    EXPECT_EQ(bytes, SavedBytes(Vocabulary::Train(blocks, o, &one, nullptr), dir));
    EXPECT_EQ(bytes, SavedBytes(Vocabulary::Train(blocks, o, &two, nullptr), dir));
    EXPECT_GT(alone.num_words(), 36u);
    o.seed = 4;
    const Vocabulary other = Vocabulary::Train(blocks, o, &two, nullptr);
    EXPECT_NE(CentroidBytes(alone), CentroidBytes(other));
    EXPECT_NE(alone.checksum(), other.checksum());
  }
}

TEST(Vocabulary, OrbCopiesOfAPrototypeShareAWord) {
  ExpectCopiesShareAWord(MakeOrb(50, 40, 6, 11), 50);
}

TEST(Vocabulary, SurfCopiesOfAPrototypeShareAWord) {
  ExpectCopiesShareAWord(MakeSurf(30, 40, 0.03, 12), 30);
}

TEST(Vocabulary, WordIsTheBruteForceDescent) {
  for (const Synthetic& s : {MakeOrb(40, 30, 10, 5), MakeSurf(40, 30, 0.1, 5)}) {
    SCOPED_TRACE(FeatureTypeName(s.type));
    const Vocabulary v = Vocabulary::Train(s.Blocks(), Options(4, 4), nullptr, nullptr);
    for (size_t r = 0; r < s.rows(); ++r) {
      for (int level = 0; level <= 5; ++level) {
        uint32_t node = 0, expected_node = 0;
        const uint32_t word = v.Word(s.Row(r), level, &node);
        ASSERT_EQ(word, BruteForceWord(v, s.Row(r), level, &expected_node)) << "row " << r;
        ASSERT_EQ(node, expected_node) << "row " << r << " level " << level;
        const Vocabulary::Node& n = v.node(node);
        EXPECT_TRUE(static_cast<int>(n.level) == level ||
                    (n.num_children == 0 && static_cast<int>(n.level) < level));
      }
      EXPECT_EQ(v.Word(s.Row(r)), v.Word(s.Row(r), 2, nullptr));
    }
  }
}

// The batched descent (rows going down together, prefetching ahead) gives
// every row the brute-force word and node, with and without nodes asked for.
TEST(Vocabulary, WordsOfManyRowsAreTheBruteForceDescent) {
  for (const Synthetic& s : {MakeOrb(40, 30, 10, 6), MakeSurf(40, 30, 0.1, 6)}) {
    SCOPED_TRACE(FeatureTypeName(s.type));
    const Vocabulary v = Vocabulary::Train(s.Blocks(), Options(4, 4), nullptr, nullptr);
    const int count = static_cast<int>(s.rows());
    ASSERT_GT(count, 100);
    for (int level = -1; level <= 5; ++level) {
      std::vector<uint32_t> words(count, UINT32_MAX), nodes(count, UINT32_MAX);
      v.Words(s.Row(0), count, level, words.data(), nodes.data());
      std::vector<uint32_t> words_only(count, UINT32_MAX);
      v.Words(s.Row(0), count, level, words_only.data(), nullptr);
      for (int r = 0; r < count; ++r) {
        uint32_t expected_node = 0;
        const uint32_t expected = BruteForceWord(v, s.Row(r), level, &expected_node);
        ASSERT_EQ(words[r], expected) << "row " << r << " level " << level;
        ASSERT_EQ(words_only[r], expected) << "row " << r << " level " << level;
        if (level >= 0) {
          ASSERT_EQ(nodes[r], expected_node) << "row " << r << " level " << level;
        } else {
          ASSERT_EQ(nodes[r], UINT32_MAX) << "row " << r << ": no level, no node written";
        }
      }
    }
  }
}

TEST(Vocabulary, TreeShapeAndEarlyLeaves) {
  // 1000 rows, branching 10: the third level's nodes hold about 10 rows, so
  // many of them stop before depth 4.
  const Synthetic s = MakeOrb(50, 20, 10, 9);
  const Vocabulary v = Vocabulary::Train(s.Blocks(), Options(10, 4), nullptr, nullptr);
  EXPECT_EQ(v.branching(), 10);
  EXPECT_EQ(v.depth(), 4);
  uint32_t leaves = 0;
  bool early_leaf = false;
  for (uint32_t i = 0; i < v.num_nodes(); ++i) {
    const Vocabulary::Node& n = v.node(i);
    if (n.num_children == 0) {
      EXPECT_EQ(n.word, leaves++);
      early_leaf |= static_cast<int>(n.level) < v.depth();
    } else {
      EXPECT_EQ(n.word, Vocabulary::kNoWord);
      EXPECT_GE(n.num_children, 2u);
      EXPECT_LE(n.num_children, 10u);
      EXPECT_GT(n.first_child, i);
      EXPECT_LT(static_cast<int>(n.level), v.depth());
    }
  }
  EXPECT_EQ(leaves, v.num_words());
  EXPECT_TRUE(early_leaf);
}

TEST(Vocabulary, IdenticalRowsMakeOneWord) {
  Synthetic s = MakeOrb(1, 30, 0, 3);
  const Vocabulary v = Vocabulary::Train(s.Blocks(), Options(4, 3), nullptr, nullptr);
  EXPECT_EQ(v.num_nodes(), 1u);
  EXPECT_EQ(v.num_words(), 1u);
  uint32_t node = 7;
  EXPECT_EQ(v.Word(s.Row(0), 2, &node), 0u);
  EXPECT_EQ(node, 0u);
}

TEST(Vocabulary, IdfCountsDocuments) {
  const Synthetic s = MakeOrb(30, 20, 6, 21);
  const std::vector<DescriptorBlock> blocks = s.Blocks();
  ProgressBar progress("test", 1, /*enabled=*/false);
  VocabularyOptions o = Options(4, 3);
  const Vocabulary v = Vocabulary::Train(blocks, o, nullptr, &progress);
  EXPECT_EQ(progress.done(), Vocabulary::TrainingWork(blocks, o));
  EXPECT_EQ(Vocabulary::TrainingWork(blocks, o), s.rows() * 3 + blocks.size());
  std::vector<int> documents(v.num_words(), 0);
  for (const DescriptorBlock& b : blocks) {
    std::vector<bool> seen(v.num_words(), false);
    for (int r = 0; r < b.rows; ++r) seen[v.Word(b.Row(r))] = true;
    for (uint32_t w = 0; w < v.num_words(); ++w) documents[w] += seen[w];
  }
  const double n = static_cast<double>(blocks.size());
  for (uint32_t w = 0; w < v.num_words(); ++w) {
    EXPECT_NEAR(v.Idf(w), std::log(n / std::max(documents[w], 1)), 1e-6) << "word " << w;
  }
}

TEST(Vocabulary, SaveOpenRoundTrip) {
  TempDir dir;
  for (const Synthetic& s : {MakeOrb(50, 20, 8, 31), MakeSurf(50, 20, 0.05, 31)}) {
    SCOPED_TRACE(FeatureTypeName(s.type));
    const Vocabulary trained = Vocabulary::Train(s.Blocks(), Options(5, 3), nullptr, nullptr);
    const std::string path = dir.Path("vocabulary.bin");
    trained.Save(path);
    const Vocabulary opened = Vocabulary::Open(path);
    EXPECT_EQ(opened.type(), trained.type());
    EXPECT_EQ(opened.row_bytes(), trained.row_bytes());
    EXPECT_EQ(opened.num_nodes(), trained.num_nodes());
    EXPECT_EQ(opened.num_words(), trained.num_words());
    EXPECT_EQ(opened.branching(), trained.branching());
    EXPECT_EQ(opened.depth(), trained.depth());
    EXPECT_EQ(opened.checksum(), trained.checksum());
    EXPECT_EQ(opened.file_bytes(), trained.file_bytes());
    ASSERT_GE(s.rows(), 1000u);
    for (size_t r = 0; r < 1000; ++r) {
      uint32_t a = 0, b = 0;
      ASSERT_EQ(opened.Word(s.Row(r), 2, &a), trained.Word(s.Row(r), 2, &b));
      ASSERT_EQ(a, b);
    }
    for (uint32_t w = 0; w < trained.num_words(); ++w) EXPECT_EQ(opened.Idf(w), trained.Idf(w));
    // A copy and a move share or keep the mapped arrays.
    Vocabulary copy = opened;
    const Vocabulary moved = std::move(copy);
    EXPECT_EQ(moved.Word(s.Row(5)), trained.Word(s.Row(5)));
    const std::string bytes = ReadFileToString(path);
    EXPECT_EQ(SavedBytes(opened, dir), bytes);
    EXPECT_EQ(opened.checksum(),
              flat_file::ReadHeader<VocabularyFileHeader>(bytes.data()).header_checksum);
  }
}

class VocabularyFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const Synthetic s = MakeOrb(20, 10, 8, 41);
    vocabulary_ = std::make_unique<Vocabulary>(
        Vocabulary::Train(s.Blocks(), Options(3, 3), nullptr, nullptr));
    good_ = SavedBytes(*vocabulary_, dir_);
    flat_file::Layout layout(UINT64_MAX);
    nodes_ = layout.Add(vocabulary_->num_nodes(), 16);
    layout.Add(vocabulary_->num_nodes(), 32);
    idf_ = layout.Add(vocabulary_->num_words(), 4);
    ASSERT_EQ(layout.end(), good_.size());
  }

  // Opening `bytes` fails with CorruptDatabase naming the file and
  // saying `what`.
  ::testing::AssertionResult Rejects(const std::string& bytes, const std::string& what) {
    const std::string path = dir_.Write("damaged.bin", bytes);
    return ThrowsWith<CorruptDatabase>([&] { Vocabulary::Open(path); }, {path, what});
  }
  // `good_` with node `index` or the header changed by `edit`, resealed so
  // that the checksums hold.
  template <typename Edit>
  std::string WithNode(uint32_t index, Edit edit) const {
    Vocabulary::Node node = vocabulary_->node(index);
    edit(node);
    return flat_file::Patched(good_, nodes_ + sizeof(node) * index, node);
  }
  template <typename Edit>
  std::string WithHeader(Edit edit) const {
    auto header = flat_file::ReadHeader<VocabularyFileHeader>(good_.data());
    edit(header);
    return flat_file::Patched(good_, 0, header);
  }
  // The first internal node other than the root, and the first leaf.
  uint32_t Internal() const {
    for (uint32_t i = 1; i < vocabulary_->num_nodes(); ++i) {
      if (vocabulary_->node(i).num_children > 0) return i;
    }
    return 0;
  }
  uint32_t Leaf(int skip = 0) const {
    for (uint32_t i = 0; i < vocabulary_->num_nodes(); ++i) {
      if (vocabulary_->node(i).num_children == 0 && skip-- == 0) return i;
    }
    return 0;
  }

  TempDir dir_;
  std::unique_ptr<Vocabulary> vocabulary_;
  std::string good_;
  uint64_t nodes_ = 0, idf_ = 0;
};

TEST_F(VocabularyFileTest, OpenAcceptsTheGoodFile) {
  EXPECT_EQ(Vocabulary::Open(dir_.Write("good.bin", good_)).checksum(), vocabulary_->checksum());
  EXPECT_GT(Internal(), 0u);
}

TEST_F(VocabularyFileTest, OpenRejectsTruncatedFiles) {
  for (size_t size = 0; size < good_.size(); size += size < 256 ? 1 : 7)
    ASSERT_TRUE(Rejects(good_.substr(0, size), "truncated")) << size;
  ASSERT_TRUE(Rejects(good_ + std::string(64, '\0'), "trailing bytes"));
}

TEST_F(VocabularyFileTest, OpenRejectsEveryFlippedByte) {
  // Header, node table, centroids and idf: every byte.
  for (size_t i = 0; i < good_.size(); ++i) {
    std::string bytes = good_;
    bytes[i] = static_cast<char>(bytes[i] ^ (1 << (i % 8)));
    ASSERT_TRUE(Rejects(bytes, "")) << "byte " << i;
  }
  std::string payload = good_;
  payload[idf_] ^= 1;
  EXPECT_TRUE(Rejects(payload, "payload checksum mismatch"));
  std::string header = good_;
  header[40] ^= 1;
  EXPECT_TRUE(Rejects(header, "header checksum mismatch"));
}

TEST_F(VocabularyFileTest, OpenRejectsWrongMagicAndVersion) {
  std::string magic = good_;
  magic[3] = 'X';
  EXPECT_TRUE(Rejects(magic, "not a placedb vocabulary file (wrong magic)"));
  EXPECT_TRUE(Rejects(std::string(300, 'x'), "wrong magic"));
  EXPECT_TRUE(Rejects(WithHeader([](VocabularyFileHeader& h) { h.common.version = 2; }),
                      "format version 2 is not supported"));
}

TEST_F(VocabularyFileTest, OpenRejectsBadHeaderFields) {
  using H = VocabularyFileHeader;
  const uint32_t n = vocabulary_->num_nodes(), words = vocabulary_->num_words();
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { h.feature_type = 3; }), "unknown feature type 3"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { h.row_bytes = 64; }), "rows cannot be 64 bytes"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { h.branching = 1; }), "branching"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { h.depth = 0; }), "depth"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { h.iterations = 0; }), "iterations"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { h.num_nodes = 0; }), "cannot have 0 nodes"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { h.num_nodes = 100000; }), "cannot have 100000 nodes"));
  EXPECT_TRUE(Rejects(WithHeader([&](H& h) { h.num_nodes = n - 1; }), ""));
  EXPECT_TRUE(Rejects(WithHeader([&](H& h) { h.num_words = n + 1; }), "words are impossible"));
  EXPECT_TRUE(Rejects(WithHeader([&](H& h) { h.num_words = words - 1; }), "does not match"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { h.reserved0 = 1; }), "reserved"));
  EXPECT_TRUE(Rejects(WithHeader([](H& h) { h.reserved[1] = 1; }), "reserved"));
}

TEST_F(VocabularyFileTest, OpenRejectsBadTrees) {
  using Node = Vocabulary::Node;
  const uint32_t n = vocabulary_->num_nodes();
  const uint32_t internal = Internal();
  const uint32_t leaf = Leaf();
  EXPECT_TRUE(
      Rejects(WithNode(0, [&](Node& x) { x.first_child = n + 5; }), "children start at node"));
  EXPECT_TRUE(Rejects(WithNode(internal, [](Node& x) { x.first_child = 0; }),  // a cycle
                      "children start at node 0"));
  EXPECT_TRUE(Rejects(WithNode(internal, [&](Node& x) { x.first_child = internal; }),
                      "children start at node"));
  EXPECT_TRUE(
      Rejects(WithNode(0, [](Node& x) { x.num_children = 4; }), "4 children (2 to 3 expected)"));
  EXPECT_TRUE(Rejects(WithNode(0, [](Node& x) { x.num_children = 1; }), "1 children"));
  // The last internal node loses its last child, the last node.
  uint32_t last = n - 1;
  while (vocabulary_->node(last).num_children == 0) --last;
  ASSERT_EQ(vocabulary_->node(last).num_children, 3u);
  EXPECT_TRUE(Rejects(WithNode(last, [](Node& x) { x.num_children = 2; }),
                      "node " + std::to_string(n - 1) + " has no parent"));
  EXPECT_TRUE(Rejects(WithNode(0, [](Node& x) { x.word = 0; }), "internal node 0 has word 0"));
  EXPECT_TRUE(Rejects(WithNode(0, [](Node& x) { x.level = 1; }), "the root is at level 1"));
  EXPECT_TRUE(Rejects(WithNode(internal, [](Node& x) { x.level = 2; }), "level"));
  EXPECT_TRUE(Rejects(WithNode(leaf, [](Node& x) { x.first_child = 3; }), "has a first child"));
  const uint32_t next_word = vocabulary_->node(Leaf(1)).word;
  EXPECT_TRUE(Rejects(WithNode(leaf, [&](Node& x) { x.word = next_word; }), "words number"));
  EXPECT_TRUE(
      Rejects(WithNode(leaf, [](Node& x) { x.word = Vocabulary::kNoWord; }), "words number"));
  // The last node, a leaf, turned into a parent of children beyond the table.
  EXPECT_TRUE(Rejects(WithNode(n - 1,
                               [&](Node& x) {
                                 x = Node{n, 2, Vocabulary::kNoWord, x.level};
                               }),
                      "beyond"));
}

TEST_F(VocabularyFileTest, ResealedRandomDamageNeverCrashes) {
  // Damage the checksums cannot catch: whatever opens must descend safely.
  std::mt19937_64 rng(8);
  const Synthetic s = MakeOrb(20, 10, 8, 41);
  int opened = 0;
  for (int trial = 0; trial < 400; ++trial) {
    std::string bytes = good_;
    for (int k = 0; k < 1 + trial % 3; ++k) {
      const size_t at = 32 + rng() % (bytes.size() - 32 - 8);
      bytes[at] = static_cast<char>(trial % 2 == 0 ? rng() : bytes[at] ^ (1 << (rng() % 8)));
    }
    flat_file::Reseal(&bytes);
    const std::string path = dir_.Write("fuzzed.bin", bytes);
    try {
      const Vocabulary v = Vocabulary::Open(path);
      for (size_t r = 0; r < s.rows(); ++r) ASSERT_LT(v.Word(s.Row(r)), v.num_words());
      ++opened;
    } catch (const CorruptDatabase&) {
    }
  }
  EXPECT_GT(opened, 0);  // centroid bits may take any value
}

TEST_F(VocabularyFileTest, OpenRejectsBadIdf) {
  for (const float value :
       {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), -0.5f}) {
    EXPECT_TRUE(Rejects(flat_file::Patched(good_, idf_ + 4, value), "word 1 has idf")) << value;
  }
}

TEST(Vocabulary, OpenRejectsNonFiniteSurfCentroids) {
  TempDir dir;
  const Synthetic s = MakeSurf(10, 10, 0.05, 3);
  const Vocabulary v = Vocabulary::Train(s.Blocks(), Options(3, 2), nullptr, nullptr);
  const std::string bytes = SavedBytes(v, dir);
  flat_file::Layout layout(UINT64_MAX);
  layout.Add(v.num_nodes(), 16);
  const uint64_t centroids = layout.Add(v.num_nodes(), 256);
  const std::string path = dir.Write(
      "surf.bin",
      flat_file::Patched(bytes, centroids + 256 + 8, std::numeric_limits<float>::infinity()));
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { Vocabulary::Open(path); },
                                          {path, "centroid is not finite"}));
  EXPECT_TRUE(
      ThrowsWith<NotFound>([&] { Vocabulary::Open(dir.Path("missing.bin")); }, "missing.bin"));
}

}  // namespace
}  // namespace placedb
