#include "placedb/retrieval/vocabulary.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstddef>
#include <functional>
#include <iterator>
#include <limits>
#include <new>
#include <random>
#include <type_traits>

#include "placedb/match/hamming.h"
#include "placedb/match/l2_distance.h"
#include "placedb/util/check.h"
#include "placedb/util/checksum.h"
#include "placedb/util/file_io.h"
#include "placedb/util/options.h"
#include "placedb/util/progress.h"
#include "placedb/util/thread_pool.h"

namespace placedb {

// Node records are used in place from the file; the header is copied.
static_assert(std::is_standard_layout<Vocabulary::Node>::value && sizeof(Vocabulary::Node) == 16,
              "Vocabulary::Node is the 16-byte node record");
static_assert(sizeof(flat_file::CommonHeader) == 32, "the common header is 32 bytes");
static_assert(offsetof(VocabularyFileHeader, feature_type) == 32 &&
                  offsetof(VocabularyFileHeader, seed) == 64 &&
                  offsetof(VocabularyFileHeader, header_checksum) ==
                      flat_file::kHeaderChecksumOffset &&
                  sizeof(VocabularyFileHeader) == flat_file::kHeaderBytes,
              "the vocabulary header's layout");

// ---- the vocabulary -----------------------------------------------------------

namespace {

// Where the sections of a vocabulary file of `nodes` nodes and `words` words lie.
struct SectionOffsets {
  explicit SectionOffsets(uint64_t limit) : layout(limit) {}
  flat_file::Layout layout;
  uint64_t nodes = 0, centroids = 0, idf = 0;
};
SectionOffsets VocabularySections(uint64_t nodes, uint64_t row_bytes, uint64_t words,
                                  uint64_t limit) {
  SectionOffsets s(limit);
  s.nodes = s.layout.Add(nodes, sizeof(Vocabulary::Node));
  s.centroids = s.layout.Add(nodes, row_bytes);
  s.idf = s.layout.Add(words, sizeof(float));
  return s;
}

bool ValidWidth(FeatureType type, int row_bytes) {
  return type == FeatureType::kOrb ? row_bytes == 32 : (row_bytes == 256 || row_bytes == 512);
}

// The most nodes a tree of this shape can have: 1 + k + ... + k^depth.
uint64_t MaxNodes(uint64_t branching, int depth) {
  uint64_t total = 0, level = 1;
  for (int d = 0; d <= depth; ++d, level *= branching) total += level;
  return total;
}

// Index of the closest of `count` rows stored back to back at `rows` (ties:
// the lower index): Hamming distance for ORB, L2 for SURF. Training and
// Word() both use it, so a tree is descended by the distance it was built
// with. A row at NaN distance from every candidate takes the first.
int Nearest(FeatureType type, int row_bytes, const uint8_t* row, const uint8_t* rows, int count) {
  if (type == FeatureType::kOrb) return TwoNearestHamming(row, rows, count, row_bytes).best_index;
  const int best =
      TwoNearestL2(reinterpret_cast<const float*>(row), reinterpret_cast<const float*>(rows), count,
                   row_bytes / 4, nullptr, 0)
          .best_index;
  return best < 0 ? 0 : best;
}

// Squared distance (the k-means++ seeding weight).
double SquaredDistance(FeatureType type, int row_bytes, const uint8_t* a, const uint8_t* b) {
  if (type == FeatureType::kOrb) {
    const double d = Hamming(a, b, row_bytes);
    return d * d;
  }
  return L2Squared(reinterpret_cast<const float*>(a), reinterpret_cast<const float*>(b),
                   row_bytes / 4);
}

// Random numbers defined here, not by the standard library's distributions,
// so that a seed gives the same vocabulary with any standard library.
uint64_t SplitMix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}
// The seed of one random stream of a training run: stream 0 samples the
// training rows, stream 1 + n clusters node n.
uint64_t StreamSeed(uint64_t seed, uint64_t stream) {
  return SplitMix64(seed ^ SplitMix64(stream));
}
// Uniform in [0, n) (multiply-shift; the bias, below n / 2^64, is immaterial).
uint64_t UniformBelow(std::mt19937_64& rng, uint64_t n) {
  return static_cast<uint64_t>((static_cast<unsigned __int128>(rng()) * n) >> 64);
}
// Uniform in [0, 1).
double Uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

// Runs fn(begin, end) over chunks of kChunkRows rows of [0, n): the chunks,
// not the threads, decide what is computed together.
constexpr size_t kChunkRows = 4096;
void ForEachChunk(ThreadPool* pool, size_t n, const std::function<void(size_t, size_t)>& fn) {
  ForEach(pool, (n + kChunkRows - 1) / kChunkRows,
          [&](size_t c) { fn(c * kChunkRows, std::min(n, (c + 1) * kChunkRows)); });
}

using Rows = std::vector<const uint8_t*>;

// How a node's rows split: the centres and rows of its non-empty clusters,
// nothing when the node stays a leaf.
struct Split {
  std::vector<uint8_t> centers;  // clusters x row bytes
  std::vector<Rows> rows;        // per cluster, in the node's row order
};

// Clusters one node's rows (see Vocabulary::Train).
class NodeClusterer {
 public:
  NodeClusterer(FeatureType type, int row_bytes, const VocabularyOptions& options, ThreadPool* pool)
      : type_(type), row_bytes_(row_bytes), options_(options), pool_(pool) {}

  Split Cluster(const Rows& rows, uint32_t node) const {
    std::mt19937_64 rng(StreamSeed(options_.seed, 1 + uint64_t{node}));
    Split split;
    split.centers = SeedCenters(rows, &rng);
    const int k = static_cast<int>(split.centers.size() / row_bytes_);
    if (k < 2) return Split();
    std::vector<uint32_t> labels(rows.size(), UINT32_MAX);
    std::vector<std::vector<uint32_t>> members;
    for (int iteration = 0; iteration < options_.iterations; ++iteration) {
      if (!Assign(rows, split.centers, k, &labels)) break;
      members = Members(labels, k);
      Update(rows, members, &split.centers);
    }
    // The centres are their members' centroids: the last step was an update,
    // or an assignment that changed nothing after one.
    std::vector<uint8_t> kept;
    for (int c = 0; c < k; ++c) {
      if (members[c].empty()) continue;
      const uint8_t* center = split.centers.data() + static_cast<size_t>(c) * row_bytes_;
      kept.insert(kept.end(), center, center + row_bytes_);
      Rows& out = split.rows.emplace_back();
      out.reserve(members[c].size());
      for (const uint32_t i : members[c]) out.push_back(rows[i]);
    }
    if (split.rows.size() < 2) return Split();
    split.centers = std::move(kept);
    return split;
  }

 private:
  // k-means++ seeding: the first centre uniformly, each next one with
  // probability proportional to the squared distance to the closest centre
  // so far. Fewer than `branching` centres when the rows run out of distinct
  // values.
  std::vector<uint8_t> SeedCenters(const Rows& rows, std::mt19937_64* rng) const {
    const size_t n = rows.size();
    std::vector<uint8_t> centers;
    centers.reserve(static_cast<size_t>(options_.branching) * row_bytes_);
    std::vector<double> d2(n, std::numeric_limits<double>::infinity());
    size_t pick = UniformBelow(*rng, n);
    for (int c = 0;; ++c) {
      centers.insert(centers.end(), rows[pick], rows[pick] + row_bytes_);
      if (c + 1 == options_.branching) break;
      const uint8_t* center = rows[pick];
      ForEachChunk(pool_, n, [&](size_t begin, size_t end) {
        for (size_t i = begin; i < end; ++i)
          d2[i] = std::min(d2[i], SquaredDistance(type_, row_bytes_, rows[i], center));
      });
      double total = 0.0;
      for (const double d : d2) total += d;
      if (!(total > 0.0)) break;
      const double target = Uniform01(*rng) * total;
      double cumulative = 0.0;
      pick = n;
      for (size_t i = 0; i < n && pick == n; ++i) {
        cumulative += d2[i];
        if (cumulative > target) pick = i;
      }
      if (pick == n) {  // rounding: the last row that can be picked
        pick = n - 1;
        while (d2[pick] == 0.0) --pick;
      }
    }
    return centers;
  }

  // Assigns every row to its closest centre; whether any label changed.
  bool Assign(const Rows& rows, const std::vector<uint8_t>& centers, int k,
              std::vector<uint32_t>* labels) const {
    const size_t n = rows.size();
    std::vector<uint8_t> changed((n + kChunkRows - 1) / kChunkRows, 0);
    ForEachChunk(pool_, n, [&](size_t begin, size_t end) {
      bool any = false;
      for (size_t i = begin; i < end; ++i) {
        const auto label =
            static_cast<uint32_t>(Nearest(type_, row_bytes_, rows[i], centers.data(), k));
        any |= label != (*labels)[i];
        (*labels)[i] = label;
      }
      changed[begin / kChunkRows] = any;
    });
    return std::any_of(changed.begin(), changed.end(), [](uint8_t c) { return c != 0; });
  }

  static std::vector<std::vector<uint32_t>> Members(const std::vector<uint32_t>& labels, int k) {
    std::vector<std::vector<uint32_t>> members(k);
    for (uint32_t i = 0; i < labels.size(); ++i) members[labels[i]].push_back(i);
    return members;
  }

  // Each non-empty cluster's centre becomes its members' centroid (summed in
  // row order, one cluster per task); an empty cluster keeps its centre.
  void Update(const Rows& rows, const std::vector<std::vector<uint32_t>>& members,
              std::vector<uint8_t>* centers) const {
    ForEach(pool_, members.size(), [&](size_t c) {
      const std::vector<uint32_t>& m = members[c];
      if (m.empty()) return;
      uint8_t* center = centers->data() + c * row_bytes_;
      if (type_ == FeatureType::kOrb) {
        std::vector<uint32_t> ones(static_cast<size_t>(row_bytes_) * 8, 0);
        for (const uint32_t i : m) {
          for (int byte = 0; byte < row_bytes_; ++byte) {
            for (int bit = 0; bit < 8; ++bit) ones[byte * 8 + bit] += (rows[i][byte] >> bit) & 1;
          }
        }
        for (int byte = 0; byte < row_bytes_; ++byte) {
          uint8_t value = 0;
          for (int bit = 0; bit < 8; ++bit) {
            if (2 * static_cast<size_t>(ones[byte * 8 + bit]) > m.size()) value |= 1 << bit;
          }
          center[byte] = value;
        }
      } else {
        const int dims = row_bytes_ / 4;
        std::vector<double> sum(dims, 0.0);
        for (const uint32_t i : m) {
          const auto* row = reinterpret_cast<const float*>(rows[i]);
          for (int d = 0; d < dims; ++d) sum[d] += row[d];
        }
        for (int d = 0; d < dims; ++d) {
          const auto mean = static_cast<float>(sum[d] / static_cast<double>(m.size()));
          std::memcpy(center + 4 * d, &mean, sizeof(mean));
        }
      }
    });
  }

  FeatureType type_;
  int row_bytes_;
  const VocabularyOptions& options_;
  ThreadPool* pool_;
};

// The non-empty blocks' type and width, after checking that they agree (the
// caller's blocks: InvalidArgument).
void CheckBlocks(const std::vector<DescriptorBlock>& blocks, FeatureType* type, int* row_bytes) {
  if (blocks.empty()) PLACEDB_THROW_INVALID("no descriptor blocks to train a vocabulary on");
  int first = -1;
  for (size_t i = 0; i < blocks.size(); ++i) {
    const DescriptorBlock& b = blocks[i];
    if (b.rows < 0 || (b.rows > 0 && b.data == nullptr)) {
      PLACEDB_THROW_INVALID("descriptor block ", i, " has no rows to read");
    }
    if (b.rows == 0) continue;
    if (first < 0) {
      first = static_cast<int>(i);
      if (!ValidWidth(b.type, b.row_bytes)) {
        PLACEDB_THROW_INVALID(FeatureTypeName(b.type), " descriptors cannot be ", b.row_bytes,
                              " bytes wide");
      }
    }
    const DescriptorBlock& f = blocks[first];
    if (b.type != f.type || b.row_bytes != f.row_bytes) {
      PLACEDB_THROW_INVALID("descriptor block ", i, " holds ", FeatureTypeName(b.type), " rows of ",
                            b.row_bytes, " bytes, block ", first, " ", FeatureTypeName(f.type),
                            " rows of ", f.row_bytes, " bytes");
    }
  }
  if (first < 0) PLACEDB_THROW_INVALID("no descriptor rows to train a vocabulary on");
  *type = blocks[first].type;
  *row_bytes = blocks[first].row_bytes;
}

uint64_t TotalRows(const std::vector<DescriptorBlock>& blocks) {
  uint64_t total = 0;
  for (const DescriptorBlock& b : blocks) total += static_cast<uint64_t>(std::max(b.rows, 0));
  return total;
}

// The training rows: all of them, or a uniform sample of
// max_training_descriptors (selection sampling, in row order).
Rows SampleRows(const std::vector<DescriptorBlock>& blocks, const VocabularyOptions& options) {
  const uint64_t total = TotalRows(blocks);
  const uint64_t wanted = std::min<uint64_t>(total, options.max_training_descriptors);
  std::mt19937_64 rng(StreamSeed(options.seed, 0));
  Rows rows;
  rows.reserve(static_cast<size_t>(wanted));
  uint64_t remaining = total;
  for (const DescriptorBlock& b : blocks) {
    for (int r = 0; r < b.rows; ++r, --remaining) {
      const uint64_t needed = wanted - rows.size();
      if (needed == remaining || (needed > 0 && UniformBelow(rng, remaining) < needed))
        rows.push_back(b.Row(r));
    }
  }
  return rows;
}

}  // namespace

uint64_t Vocabulary::TrainingWork(const std::vector<DescriptorBlock>& blocks,
                                  const VocabularyOptions& options) {
  const uint64_t sample =
      std::min<uint64_t>(TotalRows(blocks), std::max(options.max_training_descriptors, 0));
  return sample * static_cast<uint64_t>(std::max(options.depth, 0)) + blocks.size();
}

Vocabulary Vocabulary::Train(const std::vector<DescriptorBlock>& blocks,
                             const VocabularyOptions& options, ThreadPool* pool,
                             ProgressBar* progress) {
  PLACEDB_CHECK_OPTIONS(options);
  if (!HostIsLittleEndian()) PLACEDB_THROW_IO("placedb vocabularies need a little-endian host");
  FeatureType type;
  int row_bytes;
  CheckBlocks(blocks, &type, &row_bytes);
  Rows sample = SampleRows(blocks, options);
  const uint64_t training_rows = sample.size();
  if (type == FeatureType::kSurf) {
    for (const uint8_t* row : sample) {
      const auto* v = reinterpret_cast<const float*>(row);
      if (!std::all_of(v, v + row_bytes / 4, [](float x) { return std::isfinite(x); })) {
        PLACEDB_THROW_INVALID("a SURF descriptor row to train on is not finite");
      }
    }
  }

  // The tree, one level at a time: the nodes of a level are clustered in
  // parallel, then their children are numbered in parent order (breadth
  // first), so the numbering does not depend on which node finished first.
  const NodeClusterer clusterer(type, row_bytes, options, pool);
  std::vector<Node> nodes{Node{0, 0, kNoWord, 0}};
  std::vector<uint8_t> centroids(row_bytes, 0);
  struct Pending {
    uint32_t node;
    Rows rows;
  };
  std::vector<Pending> level_nodes;
  level_nodes.push_back({0, std::move(sample)});
  for (int level = 0; !level_nodes.empty(); ++level) {
    std::vector<Split> splits(level_nodes.size());
    ForEach(pool, level_nodes.size(), [&](size_t i) {
      Pending& p = level_nodes[i];
      if (level < options.depth && p.rows.size() >= static_cast<size_t>(options.branching))
        splits[i] = clusterer.Cluster(p.rows, p.node);
      const uint64_t levels_done = splits[i].rows.empty() ? options.depth - level : 1;
      if (progress != nullptr && levels_done > 0) progress->Advance(p.rows.size() * levels_done);
      Rows().swap(p.rows);  // its children hold their own rows
    });
    std::vector<Pending> next;
    for (size_t i = 0; i < splits.size(); ++i) {
      Split& s = splits[i];
      if (s.rows.empty()) continue;  // a leaf
      Node& parent = nodes[level_nodes[i].node];
      parent.first_child = static_cast<uint32_t>(nodes.size());
      parent.num_children = static_cast<uint32_t>(s.rows.size());
      centroids.insert(centroids.end(), s.centers.begin(), s.centers.end());
      for (Rows& rows : s.rows) {
        next.push_back({static_cast<uint32_t>(nodes.size()), std::move(rows)});
        nodes.push_back(Node{0, 0, kNoWord, static_cast<uint32_t>(level + 1)});
      }
    }
    level_nodes = std::move(next);
  }
  uint32_t num_words = 0;
  for (Node& n : nodes) {
    if (n.num_children == 0) n.word = num_words++;
  }

  const auto num_nodes = static_cast<uint32_t>(nodes.size());
  const SectionOffsets at = VocabularySections(num_nodes, row_bytes, num_words, UINT64_MAX / 4);
  char* w = nullptr;
  flat_file::Image image = flat_file::NewImage(at.layout.end(), &w);
  VocabularyFileHeader header{};
  header.feature_type = static_cast<uint32_t>(type);
  header.row_bytes = static_cast<uint32_t>(row_bytes);
  header.branching = static_cast<uint32_t>(options.branching);
  header.depth = static_cast<uint32_t>(options.depth);
  header.num_nodes = num_nodes;
  header.num_words = num_words;
  header.iterations = static_cast<uint32_t>(options.iterations);
  header.seed = options.seed;
  header.training_rows = training_rows;
  header.documents = blocks.size();
  std::memcpy(w, &header, sizeof(header));
  std::memcpy(w + at.nodes, nodes.data(), nodes.size() * sizeof(Node));
  std::memcpy(w + at.centroids, centroids.data(), centroids.size());

  // IDF: the documents (blocks) in which each word occurs, by the finished
  // tree's Words().
  Vocabulary tree;
  tree.Bind(image);
  std::vector<std::vector<uint32_t>> doc_words(blocks.size());
  ForEach(pool, blocks.size(), [&](size_t d) {
    const DescriptorBlock& b = blocks[d];
    std::vector<uint32_t>& words = doc_words[d];
    words.resize(static_cast<size_t>(std::max(b.rows, 0)));
    tree.Words(b.data, b.rows, -1, words.data(), nullptr);
    std::sort(words.begin(), words.end());
    words.erase(std::unique(words.begin(), words.end()), words.end());
    if (progress != nullptr) progress->Advance(1);
  });
  std::vector<uint32_t> documents_with(num_words, 0);
  for (const std::vector<uint32_t>& words : doc_words) {
    for (const uint32_t word : words) ++documents_with[word];
  }
  const auto documents = static_cast<double>(blocks.size());
  auto* idf = reinterpret_cast<float*>(w + at.idf);
  for (uint32_t word = 0; word < num_words; ++word) {
    idf[word] = static_cast<float>(std::log(documents / std::max(documents_with[word], 1u)));
  }
  flat_file::Seal(w, at.layout.end(), kVocabularyMagic, kVocabularyFormatVersion);
  return FromImage(std::move(image), "(trained vocabulary)");
}

void Vocabulary::Bind(flat_file::Image image) {
  const auto header = flat_file::ReadHeader<VocabularyFileHeader>(image.data);
  type_ = static_cast<FeatureType>(header.feature_type);
  row_bytes_ = static_cast<int>(header.row_bytes);
  branching_ = static_cast<int>(header.branching);
  depth_ = static_cast<int>(header.depth);
  num_nodes_ = header.num_nodes;
  num_words_ = header.num_words;
  checksum_ = header.header_checksum;
  const SectionOffsets at = VocabularySections(num_nodes_, row_bytes_, num_words_, image.size);
  nodes_ = image.At<Node>(at.nodes);
  centroids_ = image.At<uint8_t>(at.centroids);
  idf_ = image.At<float>(at.idf);
  image_ = std::move(image);
}

Vocabulary Vocabulary::FromImage(flat_file::Image image, const std::string& shown) {
  if (!HostIsLittleEndian()) PLACEDB_THROW_IO("placedb vocabularies need a little-endian host");
  auto fail = [&](const auto&... what) { PLACEDB_THROW_CORRUPT(shown, ": ", what...); };
  flat_file::CheckSealed(image, kVocabularyMagic, kVocabularyFormatVersion, "vocabulary", shown);
  const auto header = flat_file::ReadHeader<VocabularyFileHeader>(image.data);
  const uint32_t type = header.feature_type;
  if (type != static_cast<uint32_t>(FeatureType::kOrb) &&
      type != static_cast<uint32_t>(FeatureType::kSurf)) {
    fail("unknown feature type ", type);
  }
  const uint32_t row_bytes = header.row_bytes;
  if (row_bytes > 1024 || !ValidWidth(static_cast<FeatureType>(type), static_cast<int>(row_bytes)))
    fail(FeatureTypeName(static_cast<FeatureType>(type)), " rows cannot be ", row_bytes, " bytes");
  auto as_int = [](uint32_t value) { return static_cast<int>(std::min<uint32_t>(value, INT_MAX)); };
  VocabularyOptions parameters;
  parameters.branching = as_int(header.branching);
  parameters.depth = as_int(header.depth);
  parameters.iterations = as_int(header.iterations);
  const std::string reason = parameters.Check();
  if (!reason.empty()) fail("impossible training parameters: ", reason);
  if (header.reserved0 != 0 || std::any_of(std::begin(header.reserved), std::end(header.reserved),
                                           [](uint64_t v) { return v != 0; })) {
    fail("reserved header fields are not 0");
  }
  const uint32_t num_nodes = header.num_nodes;
  const uint32_t num_words = header.num_words;
  const uint32_t branching = static_cast<uint32_t>(parameters.branching);
  if (num_nodes < 1 || num_nodes > MaxNodes(branching, parameters.depth)) {
    fail("a tree of branching ", branching, " and depth ", parameters.depth, " cannot have ",
         num_nodes, " nodes");
  }
  if (num_words < 1 || num_words > num_nodes)
    fail(num_words, " words are impossible with ", num_nodes, " nodes");
  const SectionOffsets at = VocabularySections(num_nodes, row_bytes, num_words, image.size);
  if (at.layout.overflowed() || at.layout.end() != image.size) {
    fail("the file's size (", image.size, " bytes) does not match its ", num_nodes, " nodes and ",
         num_words, " words");
  }
  if (!at.layout.PaddingIsZero(image.data)) fail("the padding between sections is not 0");

  // The tree: children breadth first (so each has one parent and a larger
  // index: no cycle), counts and levels in range, words numbering the leaves.
  const Node* nodes = image.At<Node>(at.nodes);
  if (nodes[0].level != 0) fail("the root is at level ", nodes[0].level, ", not 0");
  uint32_t next_child = 1, next_word = 0;
  for (uint32_t i = 0; i < num_nodes; ++i) {
    const Node& n = nodes[i];
    if (i > 0 && i >= next_child) fail("node ", i, " has no parent");
    if (n.num_children == 0) {
      if (n.first_child != 0) fail("leaf ", i, " has a first child (", n.first_child, ")");
      if (n.word != next_word) {
        fail("leaf ", i, " has word ", n.word, " where ", next_word,
             " was expected (words number the leaves in node order)");
      }
      ++next_word;
      continue;
    }
    if (n.num_children < 2 || n.num_children > branching)
      fail("node ", i, " has ", n.num_children, " children (2 to ", branching, " expected)");
    if (n.word != kNoWord) fail("internal node ", i, " has word ", n.word);
    if (n.first_child != next_child) {
      fail("node ", i, "'s children start at node ", n.first_child, " where ", next_child,
           " was expected (children follow their parents breadth first)");
    }
    if (n.num_children > num_nodes - next_child)
      fail("node ", i, "'s children lie beyond the ", num_nodes, " nodes");
    if (n.level >= static_cast<uint32_t>(parameters.depth))
      fail("node ", i, " at level ", n.level, " has children below the depth ", parameters.depth);
    for (uint32_t c = n.first_child; c < n.first_child + n.num_children; ++c) {
      if (nodes[c].level != n.level + 1)
        fail("node ", c, " is at level ", nodes[c].level, " below a node at level ", n.level);
    }
    next_child += n.num_children;
  }
  if (next_word != num_words)
    fail("the tree has ", next_word, " leaves but the header says ", num_words, " words");
  const float* idf = image.At<float>(at.idf);
  for (uint32_t word = 0; word < num_words; ++word) {
    if (!(std::isfinite(idf[word]) && idf[word] >= 0.0f))
      fail("word ", word, " has idf ", idf[word], " (finite and >= 0 expected)");
  }
  if (type == static_cast<uint32_t>(FeatureType::kSurf)) {
    const float* values = image.At<float>(at.centroids);
    const size_t count = static_cast<size_t>(num_nodes) * (row_bytes / 4);
    if (!std::all_of(values, values + count, [](float v) { return std::isfinite(v); }))
      fail("a centroid is not finite");
  }
  Vocabulary vocabulary;
  vocabulary.Bind(std::move(image));
  return vocabulary;
}

void Vocabulary::Save(const std::string& path) const { flat_file::WriteImage(image_, path); }

Vocabulary Vocabulary::Open(const std::string& path) {
  return FromMapped(MappedFile::Open(path), path);
}

Vocabulary Vocabulary::FromMapped(std::shared_ptr<const MappedFile> file,
                                  const std::string& shown_name) {
  return FromImage(flat_file::MapImage(std::move(file)), shown_name);
}

void Vocabulary::Words(const uint8_t* rows, int count, int node_level, uint32_t* words,
                       uint32_t* nodes) const {
  if (count <= 0) return;
  thread_local std::vector<uint32_t> current, passed;
  current.assign(static_cast<size_t>(count), 0);
  passed.assign(static_cast<size_t>(count), 0);
  const size_t row_bytes = static_cast<size_t>(row_bytes_);
  // Touches the children of `n` (their node records and centroid rows).
  const auto prefetch = [&](const Node& n) {
    if (n.num_children == 0) return;
    const char* c = reinterpret_cast<const char*>(Centroid(n.first_child));
    const size_t bytes = row_bytes * n.num_children;
    for (size_t o = 0; o < bytes; o += 64) __builtin_prefetch(c + o);
    __builtin_prefetch(nodes_ + n.first_child);
  };
  // Rows this far ahead have their next children prefetched.
  constexpr int kAhead = 8;
  for (int level = 0;; ++level) {
    bool descended = false;
    for (int r = 0; r < count && r < kAhead; ++r) prefetch(nodes_[current[r]]);
    for (int r = 0; r < count; ++r) {
      if (r + kAhead < count) prefetch(nodes_[current[r + kAhead]]);
      const Node& n = nodes_[current[r]];
      if (level <= node_level) passed[r] = current[r];
      if (n.num_children == 0) continue;
      current[r] = n.first_child + static_cast<uint32_t>(Nearest(
                                       type_, row_bytes_, rows + r * row_bytes,
                                       Centroid(n.first_child), static_cast<int>(n.num_children)));
      descended = true;
    }
    if (!descended) break;
  }
  for (int r = 0; r < count; ++r) {
    words[r] = nodes_[current[r]].word;
    if (nodes != nullptr && node_level >= 0) nodes[r] = passed[r];
  }
}

uint32_t Vocabulary::Word(const uint8_t* row, int node_level, uint32_t* node) const {
  uint32_t word = 0;
  Words(row, 1, node_level, &word, node);
  return word;
}

}  // namespace placedb
