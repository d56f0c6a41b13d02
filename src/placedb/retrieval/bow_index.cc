#include "placedb/retrieval/bow_index.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <functional>
#include <iterator>
#include <type_traits>

#include "placedb/util/check.h"
#include "placedb/util/checksum.h"
#include "placedb/util/file_io.h"
#include "placedb/util/options.h"
#include "placedb/util/parallel.h"
#include "placedb/util/progress.h"
#include "placedb/util/thread_pool.h"

namespace placedb {

namespace {

// A well-mixed 64-bit hash of one (word, keyframe, weight) entry (the
// finaliser of SplitMix64 over the packed fields), summed over a multiset.
uint64_t EntryHash(uint32_t word, uint32_t keyframe, float weight) {
  uint32_t bits = 0;
  std::memcpy(&bits, &weight, sizeof(bits));
  uint64_t z = (static_cast<uint64_t>(word) << 32 | keyframe) * 0x9e3779b97f4a7c15ULL ^
               (static_cast<uint64_t>(bits) + 0x632be59bd9b4e019ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

static_assert(offsetof(BowIndexFileHeader, vocabulary_checksum) == 32 &&
                  offsetof(BowIndexFileHeader, direct_node_bytes) == 52 &&
                  offsetof(BowIndexFileHeader, num_entries) == 56 &&
                  offsetof(BowIndexFileHeader, keyframe_bytes) == 80 &&
                  offsetof(BowIndexFileHeader, header_checksum) ==
                      flat_file::kHeaderChecksumOffset &&
                  sizeof(BowIndexFileHeader) == flat_file::kHeaderBytes,
              "the index header's layout");

// Where the sections of a version 3 index file lie.
struct SectionOffsets {
  explicit SectionOffsets(uint64_t limit) : layout(limit) {}
  flat_file::Layout layout;
  uint64_t ids = 0, vector_offsets = 0, direct_offsets = 0, keyframe_byte_offsets = 0, totals = 0,
           keyframe_bytes = 0, word_offsets = 0, word_byte_offsets = 0, postings = 0,
           keyframe_blocks = 0, word_blocks = 0;
};
SectionOffsets IndexSections(const BowIndexFileHeader& h, uint64_t limit) {
  SectionOffsets s(limit);
  flat_file::Layout& layout = s.layout;
  const uint64_t keyframes = h.num_keyframes, words = h.num_words;
  s.ids = layout.Add(keyframes, sizeof(int32_t));
  s.vector_offsets = layout.Add(keyframes + 1, sizeof(uint64_t));
  s.direct_offsets = layout.Add(keyframes + 1, sizeof(uint64_t));
  s.keyframe_byte_offsets = layout.Add(keyframes + 1, sizeof(uint64_t));
  s.totals = layout.Add(keyframes, sizeof(double));
  s.keyframe_bytes = layout.Add(h.keyframe_bytes, 1);
  s.word_offsets = layout.Add(words + 1, sizeof(uint64_t));
  s.word_byte_offsets = layout.Add(words + 1, sizeof(uint64_t));
  s.postings = layout.Add(h.posting_bytes, 1);
  s.keyframe_blocks = layout.Add(keyframes, sizeof(uint64_t));
  s.word_blocks = layout.Add(words, sizeof(uint64_t));
  return s;
}

// One word's term of BowScore: (|a| + |b| - |a - b|) / 2, which is
// min(|a|, |b|) when a and b have the same sign and 0 otherwise (computed so,
// exactly).
double CommonTerm(double a, double b) {
  return a * b > 0.0 ? std::min(std::abs(a), std::abs(b)) : 0.0;
}

// A word's tf-idf weight in a vector: its count times its idf, over the
// vector's total of those (L1 normalisation), in double, rounded to f32
// once. The build, the vectors and the postings all compute it here.
inline double RawWeight(uint32_t count, float idf) {
  return static_cast<double>(count) * static_cast<double>(idf);
}
inline float EntryWeight(uint32_t count, float idf, double total) {
  return static_cast<float>(RawWeight(count, idf) / total);
}

// A keyframe's or a query's words with their counts (sorted, only words of
// idf > 0), and the total of count x idf (in word order).
struct WordCounts {
  std::vector<uint32_t> words, counts;
  double total = 0.0;
};

// The words of `block`; `nodes` (optional) receives each row's node at
// `direct_level`.
WordCounts CountWords(const Vocabulary& vocabulary, int direct_level, const DescriptorBlock& block,
                      std::vector<uint32_t>* nodes) {
  if (block.rows < 0 || (block.rows > 0 && block.data == nullptr)) {
    PLACEDB_THROW_INVALID("a descriptor block without rows to read");
  }
  if (block.rows > 0 &&
      (block.type != vocabulary.type() || block.row_bytes != vocabulary.row_bytes())) {
    PLACEDB_THROW_INVALID(FeatureTypeName(block.type), " rows of ", block.row_bytes,
                          " bytes cannot be looked up in a vocabulary of ",
                          FeatureTypeName(vocabulary.type()), " rows of ", vocabulary.row_bytes(),
                          " bytes");
  }
  std::vector<uint32_t> words(block.rows);
  if (nodes != nullptr) nodes->assign(block.rows, 0);
  vocabulary.Words(block.data, block.rows, nodes != nullptr ? direct_level : -1, words.data(),
                   nodes != nullptr ? nodes->data() : nullptr);
  std::sort(words.begin(), words.end());
  WordCounts out;
  for (size_t i = 0; i < words.size();) {
    size_t end = i;
    while (end < words.size() && words[end] == words[i]) ++end;
    const uint32_t count = static_cast<uint32_t>(end - i);
    const double weight = RawWeight(count, vocabulary.Idf(words[i]));
    if (weight > 0.0) {
      out.words.push_back(words[i]);
      out.counts.push_back(count);
      out.total += weight;
    }
    i = end;
  }
  return out;
}

// tf-idf: each occurrence adds the word's idf; then L1 normalisation.
BowVector WeightedVector(const Vocabulary& vocabulary, const WordCounts& counted) {
  BowVector v;
  v.words = counted.words;
  v.weights.reserve(counted.words.size());
  for (size_t e = 0; e < counted.words.size(); ++e) {
    v.weights.push_back(
        EntryWeight(counted.counts[e], vocabulary.Idf(counted.words[e]), counted.total));
  }
  return v;
}

// The entries of version 3 (see the top of bow_index.h): LEB128 varints.
void PutVarint(uint64_t value, std::vector<uint8_t>* out) {
  while (value >= 0x80) {
    out->push_back(static_cast<uint8_t>(value | 0x80));
    value >>= 7;
  }
  out->push_back(static_cast<uint8_t>(value));
}
void PutEntry(uint32_t value, uint32_t previous_plus_one, uint32_t count,
              std::vector<uint8_t>* out) {
  PutVarint((static_cast<uint64_t>(value - previous_plus_one) << 1) | (count > 1 ? 1 : 0), out);
  if (count > 1) PutVarint(count - 2, out);
}
// Reads a varint from [*p, end): false when it runs past `end` or past 64
// bits.
bool ReadVarint(const uint8_t** p, const uint8_t* end, uint64_t* value) {
  uint64_t v = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (*p == end) return false;
    const uint8_t byte = *(*p)++;
    if (shift == 63 && byte > 1) return false;
    v |= static_cast<uint64_t>(byte & 0x7f) << shift;
    if (!(byte & 0x80)) {
      *value = v;
      return true;
    }
  }
  return false;
}
// The same on checked bytes (no bounds).
inline uint64_t ReadCheckedVarint(const uint8_t*& p) {
  uint64_t v = *p & 0x7f;
  if (!(*p++ & 0x80)) return v;
  for (int shift = 7;; shift += 7) {
    const uint8_t byte = *p++;
    v |= static_cast<uint64_t>(byte & 0x7f) << shift;
    if (!(byte & 0x80)) return v;
  }
}
// Reads `n` entries from [p, end), each value below `limit`, ascending;
// calls visit(value, count) for each. "" or why they are impossible;
// *used receives the bytes read.
template <typename Visit>
std::string ReadEntries(const uint8_t* p, const uint8_t* end, uint64_t n, uint64_t limit,
                        const Visit& visit, uint64_t* used) {
  const uint8_t* begin = p;
  uint64_t next = 0;  // the previous value + 1
  for (uint64_t e = 0; e < n; ++e) {
    uint64_t code = 0, extra = 0;
    if (!ReadVarint(&p, end, &code)) return "an entry runs past its block or past 64 bits";
    if ((code >> 1) >= limit - std::min(next, limit)) {
      return internal::JoinMessage("an entry's value is not ascending and below ", limit);
    }
    const uint64_t value = next + (code >> 1);
    if ((code & 1) && (!ReadVarint(&p, end, &extra) || extra > (uint64_t{1} << 30)))
      return "an entry's count runs past its block or is beyond 2^30";
    visit(static_cast<uint32_t>(value), static_cast<uint32_t>((code & 1) ? extra + 2 : 1));
    next = value + 1;
  }
  *used = static_cast<uint64_t>(p - begin);
  return "";
}
// The same on checked bytes; returns the end of the entries.
template <typename Visit>
inline const uint8_t* ReadCheckedEntries(const uint8_t* p, uint64_t n, const Visit& visit) {
  uint32_t next = 0;
  for (uint64_t e = 0; e < n; ++e) {
    const uint64_t code = ReadCheckedVarint(p);
    const uint32_t value = next + static_cast<uint32_t>(code >> 1);
    const uint32_t count = (code & 1) ? static_cast<uint32_t>(ReadCheckedVarint(p)) + 2 : 1;
    if (!visit(value, count)) break;
    next = value + 1;
  }
  return p;
}

// A word's postings (see the top of bow_index.h): a width byte b (1 to
// 4), then each posting's code in b bytes little-endian (keyframe -
// previous keyframe - 1), then each posting's weight (f32). Fixed-width
// codes decode without a branch or a dependency on the previous code's
// length, and the stored weight needs no arithmetic: a query reads about a
// million postings at 100 000 keyframes (measured: varint codes with
// weights computed from counts made the query's scoring twice as slow).
void PutPostings(const std::vector<uint32_t>& keyframes, const std::vector<float>& weights,
                 std::vector<uint8_t>* out) {
  if (keyframes.empty()) return;
  std::vector<uint32_t> codes(keyframes.size());
  uint32_t largest = 0, next = 0;
  for (size_t j = 0; j < keyframes.size(); ++j) {
    codes[j] = keyframes[j] - next;
    largest = std::max(largest, codes[j]);
    next = keyframes[j] + 1;
  }
  uint32_t width = 1;
  while (width < 4 && (largest >> (8 * width)) != 0) ++width;
  out->push_back(static_cast<uint8_t>(width));
  for (const uint32_t code : codes) {
    for (uint32_t b = 0; b < width; ++b) out->push_back(static_cast<uint8_t>(code >> (8 * b)));
  }
  for (const float weight : weights) {
    uint8_t bytes[sizeof(float)];
    std::memcpy(bytes, &weight, sizeof(bytes));
    out->insert(out->end(), bytes, bytes + sizeof(bytes));
  }
}
// Reads `n` postings from [p, end), keyframes below `limit`, ascending,
// weights finite and > 0; visit(keyframe, weight) for each. "" or why they
// are impossible; *used receives the bytes read.
template <typename Visit>
std::string ReadPostings(const uint8_t* p, const uint8_t* end, uint64_t n, uint64_t limit,
                         const Visit& visit, uint64_t* used) {
  *used = 0;
  if (n == 0) return "";
  if (p == end) return "the postings run past their block";
  const uint32_t width = *p;
  if (width < 1 || width > 4) return internal::JoinMessage("a width of ", width, " bytes");
  const uint8_t* codes = p + 1;
  if (static_cast<uint64_t>(end - codes) / (width + sizeof(float)) < n)
    return "the postings run past their block";
  const uint8_t* weights = codes + n * width;
  uint64_t next = 0;
  for (uint64_t j = 0; j < n; ++j) {
    uint64_t code = 0;
    for (uint32_t b = 0; b < width; ++b)
      code |= static_cast<uint64_t>(codes[j * width + b]) << (8 * b);
    if (code >= limit - std::min(next, limit))
      return internal::JoinMessage("a keyframe is not ascending and below ", limit);
    float weight = 0.0f;
    std::memcpy(&weight, weights + j * sizeof(float), sizeof(weight));
    if (!(std::isfinite(weight) && weight > 0.0f))
      return internal::JoinMessage("a weight of ", weight, " (finite and > 0 expected)");
    visit(static_cast<uint32_t>(next + code), weight);
    next += code + 1;
  }
  *used = static_cast<uint64_t>(weights + n * sizeof(float) - p);
  return "";
}

// Per-thread scratch of Query: a dense score per keyframe and an "among"
// mask, both all zero between queries (only touched entries are reset, so a
// query costs what it touches, not the keyframe count), and the list of the
// keyframes touched (room for every keyframe and one more).
struct QueryScratch {
  std::vector<double> scores;
  std::vector<uint8_t> allowed;
  std::vector<uint32_t> touched;
  size_t num_touched = 0;
};

// Puts the scratch back to all zero, also when a query throws.
class ScratchReset {
 public:
  ScratchReset(QueryScratch* scratch, const std::vector<uint32_t>* among)
      : scratch_(scratch), among_(among) {}
  ~ScratchReset() {
    for (size_t i = 0; i < scratch_->num_touched; ++i) scratch_->scores[scratch_->touched[i]] = 0.0;
    scratch_->num_touched = 0;
    if (among_ != nullptr) {
      for (const uint32_t k : *among_) scratch_->allowed[k] = 0;
    }
  }
  ScratchReset(const ScratchReset&) = delete;
  ScratchReset& operator=(const ScratchReset&) = delete;

 private:
  QueryScratch* scratch_;
  const std::vector<uint32_t>* among_;
};

// The nodes a direct entry at `level` may name, ascending: the level's
// nodes and the leaves above it.
std::vector<uint32_t> DirectNodesByRank(const Vocabulary& vocab, uint32_t level) {
  std::vector<uint32_t> out;
  for (uint32_t node = 0; node < vocab.num_nodes(); ++node) {
    const Vocabulary::Node& n = vocab.node(node);
    if (n.level == level || (n.num_children == 0 && n.level < level)) out.push_back(node);
  }
  return out;
}
uint32_t DirectNodeBytes(size_t ranks) { return ranks <= 256 ? 1 : ranks <= 65536 ? 2 : 4; }
uint32_t ReadRank(const uint8_t* p, uint32_t bytes) {
  uint32_t v = 0;
  std::memcpy(&v, p, bytes);  // little-endian host
  return v;
}

}  // namespace

double BowScore(const BowVector& a, const BowVector& b) {
  if (a.words.size() != a.weights.size() || b.words.size() != b.weights.size()) {
    PLACEDB_THROW_INVALID("a bag of words needs one weight per word");
  }
  double score = 0.0;
  size_t i = 0, j = 0;
  while (i < a.words.size() && j < b.words.size()) {
    if (a.words[i] < b.words[j]) {
      ++i;
    } else if (b.words[j] < a.words[i]) {
      ++j;
    } else {
      score += CommonTerm(a.weights[i++], b.weights[j++]);
    }
  }
  return score;
}

// The arrays of an index file image, and the checks of its blocks: one
// keyframe's vector and direct entries, one word's postings (each adds its
// entries' EntryHash to *hash, for the transposition check).
struct BowIndex::Arrays {
  const Vocabulary* vocabulary = nullptr;
  uint32_t num_keyframes = 0, num_words = 0, direct_level = 0, direct_node_bytes = 1;
  uint64_t num_ranks = 0;  // the nodes a direct entry may name
  const uint64_t* vector_offsets = nullptr;
  const uint64_t* direct_offsets = nullptr;
  const uint64_t* keyframe_byte_offsets = nullptr;
  const double* totals = nullptr;
  const uint8_t* keyframe_bytes = nullptr;
  const uint64_t* word_offsets = nullptr;
  const uint64_t* word_byte_offsets = nullptr;
  const uint8_t* postings = nullptr;

  // The arrays of an image whose sections lie at `at` (vocabulary and
  // ranks not set).
  static Arrays At(const char* base, const SectionOffsets& at, const BowIndexFileHeader& h) {
    Arrays a;
    a.num_keyframes = h.num_keyframes;
    a.num_words = h.num_words;
    a.direct_level = h.direct_level;
    a.direct_node_bytes = h.direct_node_bytes;
    a.vector_offsets = reinterpret_cast<const uint64_t*>(base + at.vector_offsets);
    a.direct_offsets = reinterpret_cast<const uint64_t*>(base + at.direct_offsets);
    a.keyframe_byte_offsets = reinterpret_cast<const uint64_t*>(base + at.keyframe_byte_offsets);
    a.totals = reinterpret_cast<const double*>(base + at.totals);
    a.keyframe_bytes = reinterpret_cast<const uint8_t*>(base + at.keyframe_bytes);
    a.word_offsets = reinterpret_cast<const uint64_t*>(base + at.word_offsets);
    a.word_byte_offsets = reinterpret_cast<const uint64_t*>(base + at.word_byte_offsets);
    a.postings = reinterpret_cast<const uint8_t*>(base + at.postings);
    return a;
  }

  // Why keyframe i's vector or direct entries are impossible, or "".
  std::string CheckKeyframe(uint32_t i, uint64_t* hash) const {
    const uint8_t* p = keyframe_bytes + keyframe_byte_offsets[i];
    const uint8_t* end = keyframe_bytes + keyframe_byte_offsets[i + 1];
    const uint64_t rows = direct_offsets[i + 1] - direct_offsets[i];
    const uint64_t direct_bytes = rows * direct_node_bytes;
    if (static_cast<uint64_t>(end - p) < direct_bytes)
      return internal::JoinMessage("keyframe ", i, "'s block is shorter than its direct entries");
    const uint8_t* vector_end = end - direct_bytes;
    uint64_t h = 0, used = 0;
    double total = 0.0;
    bool idf_ok = true;
    const std::string bad = ReadEntries(
        p, vector_end, vector_offsets[i + 1] - vector_offsets[i], num_words,
        [&](uint32_t word, uint32_t count) {
          const float idf = vocabulary->Idf(word);
          if (hash != nullptr) h += EntryHash(word, i, EntryWeight(count, idf, totals[i]));
          idf_ok = idf_ok && idf > 0.0f;
          total += RawWeight(count, idf);
        },
        &used);
    if (!bad.empty()) return internal::JoinMessage("keyframe ", i, "'s words: ", bad);
    if (p + used != vector_end)
      return internal::JoinMessage("keyframe ", i, "'s words do not fill their block");
    if (!idf_ok) return internal::JoinMessage("keyframe ", i, " has a word of idf 0");
    if (!(total == totals[i]))
      return internal::JoinMessage("keyframe ", i, "'s total ", totals[i], " is not its words' (",
                                   total, ")");
    for (uint64_t r = 0; r < rows; ++r) {
      const uint32_t rank = ReadRank(vector_end + r * direct_node_bytes, direct_node_bytes);
      if (rank >= num_ranks)
        return internal::JoinMessage("direct entry ", direct_offsets[i] + r, " (rank ", rank,
                                     ") is not a node of level ", direct_level);
    }
    if (hash != nullptr) *hash += h;
    return "";
  }
  // Why word w's postings are impossible, or "".
  std::string CheckWord(uint32_t word, uint64_t* hash) const {
    const uint64_t n = word_offsets[word + 1] - word_offsets[word];
    if (n > 0 && !(vocabulary->Idf(word) > 0.0f))
      return internal::JoinMessage("word ", word, " has idf 0 but postings");
    const uint8_t* p = postings + word_byte_offsets[word];
    const uint8_t* end = postings + word_byte_offsets[word + 1];
    uint64_t h = 0, used = 0;
    const std::string bad = ReadPostings(
        p, end, n, num_keyframes,
        [&](uint32_t keyframe, float weight) {
          if (hash != nullptr) h += EntryHash(word, keyframe, weight);
        },
        &used);
    if (!bad.empty()) return internal::JoinMessage("the postings of word ", word, ": ", bad);
    if (p + used != end)
      return internal::JoinMessage("the postings of word ", word, " do not fill their block");
    if (hash != nullptr) *hash += h;
    return "";
  }
  // What is wrong with keyframe i's block (its checksum, with `sums`; then
  // its values), or "".
  std::string KeyframeBlockProblem(uint32_t i, const uint64_t* sums, uint64_t* hash) const {
    if (sums != nullptr && KeyframeSum(i) != sums[i]) {
      return internal::JoinMessage("keyframe ", i,
                                   "'s entries fail their block checksum (the file is corrupted)");
    }
    return CheckKeyframe(i, hash);
  }
  std::string WordBlockProblem(uint32_t word, const uint64_t* sums, uint64_t* hash) const {
    if (sums != nullptr && WordSum(word) != sums[word]) {
      return internal::JoinMessage("the postings of word ", word,
                                   " fail their block checksum (the file is corrupted)");
    }
    return CheckWord(word, hash);
  }
  // The block checksums.
  uint64_t KeyframeSum(uint32_t i) const {
    return Checksum64(keyframe_bytes + keyframe_byte_offsets[i],
                      keyframe_byte_offsets[i + 1] - keyframe_byte_offsets[i]);
  }
  uint64_t WordSum(uint32_t word) const {
    return Checksum64(postings + word_byte_offsets[word],
                      word_byte_offsets[word + 1] - word_byte_offsets[word]);
  }
};

struct BowIndex::LazyCheck {
  std::unique_ptr<std::atomic<uint8_t>[]> keyframe_checked, word_checked;
};

BowIndex::Arrays BowIndex::MakeArrays() const {
  Arrays a;
  a.vocabulary = vocabulary_.get();
  a.num_keyframes = num_keyframes_;
  a.num_words = vocabulary_->num_words();
  a.direct_level = static_cast<uint32_t>(direct_level_);
  a.direct_node_bytes = direct_node_bytes_;
  a.num_ranks = direct_nodes_by_rank_.size();
  a.vector_offsets = vector_offsets_;
  a.direct_offsets = direct_offsets_;
  a.keyframe_byte_offsets = keyframe_byte_offsets_;
  a.totals = totals_;
  a.keyframe_bytes = keyframe_bytes_;
  a.word_offsets = word_offsets_;
  a.word_byte_offsets = word_byte_offsets_;
  a.postings = postings_;
  return a;
}

namespace {

// Marks a block checked once `problem` finds nothing wrong with it; what
// it found ("" when nothing, or when the block was checked already).
template <typename Problem>
std::string CheckAndMark(std::atomic<uint8_t>* checked, const Problem& problem) {
  if (checked->load(std::memory_order_acquire)) return "";
  std::string bad = problem();
  if (bad.empty()) checked->store(1, std::memory_order_release);
  return bad;
}
// The same, throwing CorruptDatabase "<shown>: <problem>" for damage.
template <typename Problem>
void CheckOnce(std::atomic<uint8_t>* checked, const std::string& shown, const Problem& problem) {
  const std::string bad = CheckAndMark(checked, problem);
  if (!bad.empty()) PLACEDB_THROW_CORRUPT(shown, ": ", bad);
}

}  // namespace

void BowIndex::EnsureKeyframeChecked(uint32_t index) const {
  CheckOnce(&lazy_->keyframe_checked[index], shown_,
            [&] { return MakeArrays().KeyframeBlockProblem(index, keyframe_sums_, nullptr); });
}

void BowIndex::EnsureWordChecked(uint32_t word) const {
  CheckOnce(&lazy_->word_checked[word], shown_,
            [&] { return MakeArrays().WordBlockProblem(word, word_sums_, nullptr); });
}

namespace {

// Everything of an index's arrays: every keyframe's and word's block and
// its block checksum, and the inverted file exactly the vectors
// transposed. Halves of the vectors and of the postings (split where half
// the entries lie) and `also` run at once. Throws CorruptDatabase
// "<shown>: ...".
template <typename ArraysT>
void CheckAllBlocks(const ArraysT& a, uint64_t entries, const uint64_t* keyframe_sums,
                    const uint64_t* word_sums, const std::string& shown,
                    const std::function<void()>& also) {
  // Both sides are summed as a multiset hash in sequential passes (a random
  // access per posting into the vectors would dominate the time on a large
  // database); with the counts equal, a difference shows as different
  // sums, but for a deliberately forged file (and the file is checksummed
  // as a whole). The sums add across ranges.
  const auto keyframes = [&](uint32_t first, uint32_t last, uint64_t* hash) {
    for (uint32_t i = first; i < last; ++i) {
      const std::string bad = a.KeyframeBlockProblem(i, keyframe_sums, hash);
      if (!bad.empty()) PLACEDB_THROW_CORRUPT(shown, ": ", bad);
    }
  };
  const auto words = [&](uint32_t first, uint32_t last, uint64_t* hash) {
    for (uint32_t w = first; w < last; ++w) {
      const std::string bad = a.WordBlockProblem(w, word_sums, hash);
      if (!bad.empty()) PLACEDB_THROW_CORRUPT(shown, ": ", bad);
    }
  };
  const uint32_t mid_keyframe = static_cast<uint32_t>(
      std::upper_bound(a.vector_offsets, a.vector_offsets + a.num_keyframes, entries / 2) -
      a.vector_offsets);
  const uint32_t mid_word = static_cast<uint32_t>(
      std::upper_bound(a.word_offsets, a.word_offsets + a.num_words, entries / 2) - a.word_offsets);
  uint64_t vector_hash[2] = {0, 0}, posting_hash[2] = {0, 0};
  RunTogether({also, [&] { keyframes(0, mid_keyframe, &vector_hash[0]); },
               [&] { keyframes(mid_keyframe, a.num_keyframes, &vector_hash[1]); },
               [&] { words(0, mid_word, &posting_hash[0]); },
               [&] { words(mid_word, a.num_words, &posting_hash[1]); }});
  if (posting_hash[0] + posting_hash[1] != vector_hash[0] + vector_hash[1]) {
    PLACEDB_THROW_CORRUPT(shown,
                          ": the inverted file disagrees with the keyframe vectors (not their "
                          "transpose)");
  }
}

// The XXH3-64 of the tables (BowIndexFileHeader::tables_checksum).
uint64_t TablesChecksum(const char* data, const SectionOffsets& at, uint64_t keyframes,
                        uint64_t words) {
  Checksum64Stream s;
  s.Update(data + at.ids, keyframes * sizeof(int32_t));
  s.Update(data + at.vector_offsets, (keyframes + 1) * sizeof(uint64_t));
  s.Update(data + at.direct_offsets, (keyframes + 1) * sizeof(uint64_t));
  s.Update(data + at.keyframe_byte_offsets, (keyframes + 1) * sizeof(uint64_t));
  s.Update(data + at.totals, keyframes * sizeof(double));
  s.Update(data + at.word_offsets, (words + 1) * sizeof(uint64_t));
  s.Update(data + at.word_byte_offsets, (words + 1) * sizeof(uint64_t));
  s.Update(data + at.keyframe_blocks, keyframes * sizeof(uint64_t));
  s.Update(data + at.word_blocks, words * sizeof(uint64_t));
  return s.Digest();
}

// Fills in the block checksums of an image's blocks whose offsets lie
// inside their sections (all of them, for an image that is built), then
// the tables checksum.
// (ArraysT: BowIndex::Arrays, named by its friends.)
template <typename ArraysT>
void SealBlocks(char* w, const SectionOffsets& at, BowIndexFileHeader* header, ThreadPool* pool) {
  const ArraysT a = ArraysT::At(w, at, *header);
  auto* keyframe_sums = reinterpret_cast<uint64_t*>(w + at.keyframe_blocks);
  auto* word_sums = reinterpret_cast<uint64_t*>(w + at.word_blocks);
  const auto inside = [](uint64_t begin, uint64_t end, uint64_t total) {
    return begin <= end && end <= total;
  };
  ForEach(pool, a.num_keyframes, [&](size_t i) {
    if (inside(a.keyframe_byte_offsets[i], a.keyframe_byte_offsets[i + 1], header->keyframe_bytes))
      keyframe_sums[i] = a.KeyframeSum(static_cast<uint32_t>(i));
  });
  ForEach(pool, a.num_words, [&](size_t word) {
    if (inside(a.word_byte_offsets[word], a.word_byte_offsets[word + 1], header->posting_bytes))
      word_sums[word] = a.WordSum(static_cast<uint32_t>(word));
  });
  header->tables_checksum = TablesChecksum(w, at, header->num_keyframes, header->num_words);
  std::memcpy(w, header, sizeof(*header));
}

}  // namespace

BowIndex BowIndex::Build(std::shared_ptr<const Vocabulary> vocabulary, const Database& db,
                         const BowIndexOptions& options, ThreadPool* pool, ProgressBar* progress) {
  PLACEDB_CHECK(vocabulary != nullptr, "a bag-of-words index needs a vocabulary");
  PLACEDB_CHECK_OPTIONS(options);
  if (options.direct_level > vocabulary->depth()) {
    PLACEDB_THROW_INVALID("`direct_level` ", options.direct_level,
                          " is deeper than the vocabulary's depth ", vocabulary->depth());
  }
  if (!db.has_features()) {
    PLACEDB_THROW_INVALID("a bag-of-words index needs a database opened with its features");
  }
  if (db.feature_type() != vocabulary->type() || db.descriptor_bytes() != vocabulary->row_bytes()) {
    PLACEDB_THROW_INVALID("the database holds ", FeatureTypeName(db.feature_type()),
                          " descriptors of ", db.descriptor_bytes(), " bytes, the vocabulary ",
                          FeatureTypeName(vocabulary->type()), " descriptors of ",
                          vocabulary->row_bytes(), " bytes");
  }
  if (db.size() >= UINT32_MAX) {
    PLACEDB_THROW_INVALID("too many keyframes for a bag-of-words index: ", db.size());
  }
  if (!HostIsLittleEndian()) PLACEDB_THROW_IO("placedb indexes need a little-endian host");

  const size_t num_keyframes = db.size();
  const uint32_t num_words = vocabulary->num_words();
  const std::vector<uint32_t> by_rank =
      DirectNodesByRank(*vocabulary, static_cast<uint32_t>(options.direct_level));
  std::vector<uint32_t> rank_of(vocabulary->num_nodes(), 0);
  for (size_t r = 0; r < by_rank.size(); ++r) rank_of[by_rank[r]] = static_cast<uint32_t>(r);
  const uint32_t node_bytes = DirectNodeBytes(by_rank.size());
  // Each keyframe's block, and what the tables and postings need of it.
  std::vector<WordCounts> counted(num_keyframes);
  std::vector<std::vector<uint8_t>> blocks(num_keyframes);
  std::vector<uint64_t> rows(num_keyframes);
  const auto transform = [&](size_t i) {
    std::vector<uint32_t> nodes;
    counted[i] = CountWords(*vocabulary, options.direct_level, db.Descriptors(i), &nodes);
    const WordCounts& c = counted[i];
    std::vector<uint8_t>& block = blocks[i];
    uint32_t next = 0;
    for (size_t e = 0; e < c.words.size(); ++e) {
      PutEntry(c.words[e], next, c.counts[e], &block);
      next = c.words[e] + 1;
    }
    for (const uint32_t node : nodes) {
      const uint32_t rank = rank_of[node];
      for (uint32_t b = 0; b < node_bytes; ++b)
        block.push_back(static_cast<uint8_t>(rank >> 8 * b));
    }
    rows[i] = nodes.size();
    if (progress != nullptr) progress->Advance(1);
  };
  ForEach(pool, num_keyframes, transform);
  // The inverted file, each word's postings in keyframe order.
  std::vector<std::vector<uint8_t>> lists(num_words);
  std::vector<uint64_t> list_entries(num_words, 0);
  uint64_t entries = 0, features = 0, keyframe_bytes = 0, posting_bytes = 0;
  {
    std::vector<std::vector<uint32_t>> list_keyframes(num_words);
    std::vector<std::vector<float>> list_weights(num_words);
    for (size_t i = 0; i < num_keyframes; ++i) {
      const WordCounts& c = counted[i];
      for (size_t e = 0; e < c.words.size(); ++e) {
        list_keyframes[c.words[e]].push_back(static_cast<uint32_t>(i));
        list_weights[c.words[e]].push_back(
            EntryWeight(c.counts[e], vocabulary->Idf(c.words[e]), c.total));
      }
      entries += c.words.size();
      features += rows[i];
      keyframe_bytes += blocks[i].size();
    }
    ForEach(pool, num_words, [&](size_t word) {
      PutPostings(list_keyframes[word], list_weights[word], &lists[word]);
      list_entries[word] = list_keyframes[word].size();
      std::vector<uint32_t>().swap(list_keyframes[word]);
      std::vector<float>().swap(list_weights[word]);
    });
  }
  for (const std::vector<uint8_t>& list : lists) posting_bytes += list.size();

  BowIndexFileHeader header{};
  header.vocabulary_checksum = vocabulary->checksum();
  header.num_keyframes = static_cast<uint32_t>(num_keyframes);
  header.direct_level = static_cast<uint32_t>(options.direct_level);
  header.num_words = num_words;
  header.direct_node_bytes = node_bytes;
  header.num_entries = entries;
  header.num_features = features;
  header.keyframe_bytes = keyframe_bytes;
  header.posting_bytes = posting_bytes;
  const SectionOffsets at = IndexSections(header, UINT64_MAX / 4);
  char* w = nullptr;
  flat_file::Image image = flat_file::NewImage(at.layout.end(), &w);
  auto* ids = reinterpret_cast<int32_t*>(w + at.ids);
  auto* vector_offsets = reinterpret_cast<uint64_t*>(w + at.vector_offsets);
  auto* direct_offsets = reinterpret_cast<uint64_t*>(w + at.direct_offsets);
  auto* byte_offsets = reinterpret_cast<uint64_t*>(w + at.keyframe_byte_offsets);
  auto* totals = reinterpret_cast<double*>(w + at.totals);
  auto* word_offsets = reinterpret_cast<uint64_t*>(w + at.word_offsets);
  auto* word_byte_offsets = reinterpret_cast<uint64_t*>(w + at.word_byte_offsets);
  uint64_t entry = 0, row = 0, byte = 0;
  for (size_t i = 0; i < num_keyframes; ++i) {
    ids[i] = db.keyframe(i).id;
    vector_offsets[i] = entry;
    direct_offsets[i] = row;
    byte_offsets[i] = byte;
    totals[i] = counted[i].total;
    std::copy(blocks[i].begin(), blocks[i].end(), w + at.keyframe_bytes + byte);
    entry += counted[i].words.size();
    row += rows[i];
    byte += blocks[i].size();
  }
  vector_offsets[num_keyframes] = entry;
  direct_offsets[num_keyframes] = row;
  byte_offsets[num_keyframes] = byte;
  entry = byte = 0;
  for (uint32_t word = 0; word < num_words; ++word) {
    word_offsets[word] = entry;
    word_byte_offsets[word] = byte;
    std::copy(lists[word].begin(), lists[word].end(), w + at.postings + byte);
    entry += list_entries[word];
    byte += lists[word].size();
  }
  word_offsets[num_words] = entry;
  word_byte_offsets[num_words] = byte;
  SealBlocks<Arrays>(w, at, &header, pool);
  flat_file::Seal(w, at.layout.end(), kBowIndexMagic, kBowIndexFormatVersion);
  return FromImage(std::move(image), "(built index)", std::move(vocabulary), db);
}

void BowIndex::Save(const std::string& path) const { flat_file::WriteImage(image_, path); }

BowIndex BowIndex::Open(const std::string& path, std::shared_ptr<const Vocabulary> vocabulary,
                        const Database& db) {
  return FromMapped(MappedFile::Open(path), path, std::move(vocabulary), db);
}

std::pair<uint64_t, uint64_t> BowIndex::PostingsExtent() const {
  if (postings_ == nullptr || image_.data == nullptr) return {0, 0};
  return {static_cast<uint64_t>(reinterpret_cast<const char*>(postings_) - image_.data),
          posting_bytes_};
}

BowIndex BowIndex::FromMapped(std::shared_ptr<const MappedFile> file, const std::string& shown,
                              std::shared_ptr<const Vocabulary> vocabulary, const Database& db) {
  BowIndex index = FromImage(flat_file::MapImage(file), shown, std::move(vocabulary), db);
  // A version 1 or 2 file was rebuilt in memory: nothing of it is used.
  if (index.image_.data == file->data()) index.mapping_ = std::move(file);
  return index;
}

BowIndex BowIndex::FromImage(flat_file::Image image, const std::string& shown,
                             std::shared_ptr<const Vocabulary> vocabulary, const Database& db) {
  PLACEDB_CHECK(vocabulary != nullptr, "a bag-of-words index needs a vocabulary");
  if (!HostIsLittleEndian()) PLACEDB_THROW_IO("placedb indexes need a little-endian host");
  auto fail = [&](const auto&... what) { PLACEDB_THROW_CORRUPT(shown, ": ", what...); };
  // Versions 1 and 2 are accepted too: the header check is for the version
  // it says.
  uint32_t version = kBowIndexFormatVersion;
  if (image.size >= flat_file::kHeaderBytes) {
    const uint32_t said = flat_file::ReadHeader<BowIndexFileHeader>(image.data).common.version;
    if (said >= kOldestBowIndexFormatVersion && said <= kBowIndexFormatVersion) version = said;
  }
  // The payload's checksum is checked per block, on first use.
  flat_file::CheckSealedHeader(image, kBowIndexMagic, version, "bag-of-words index", shown);
  const auto header = flat_file::ReadHeader<BowIndexFileHeader>(image.data);
  const Vocabulary& vocab = *vocabulary;
  if (header.vocabulary_checksum != vocab.checksum()) {
    fail("built with another vocabulary (the index was built with vocabulary ",
         ChecksumHex(header.vocabulary_checksum), ", the one given is ",
         ChecksumHex(vocab.checksum()), ")");
  }
  const uint32_t num_keyframes = header.num_keyframes;
  const uint32_t direct_level = header.direct_level;
  const uint32_t num_words = header.num_words;
  const uint64_t entries = header.num_entries;
  const uint64_t features = header.num_features;
  if (num_words != vocab.num_words())
    fail("the index counts ", num_words, " words, its vocabulary ", vocab.num_words());
  if (direct_level > static_cast<uint32_t>(vocab.depth()))
    fail("direct level ", direct_level, " is deeper than the vocabulary's depth ", vocab.depth());
  const bool old = version < 3;
  if ((old && (header.direct_node_bytes != 0 || header.keyframe_bytes != 0 ||
               header.posting_bytes != 0 || (version == 1 && header.tables_checksum != 0))) ||
      std::any_of(std::begin(header.reserved), std::end(header.reserved),
                  [](uint64_t v) { return v != 0; })) {
    fail("reserved header fields are not 0");
  }
  if (num_keyframes != db.size()) {
    fail("built with another database (the index holds ", num_keyframes,
         " keyframes, the database ", db.size(), ")");
  }
  if (db.feature_type() != vocab.type() || db.descriptor_bytes() != vocab.row_bytes()) {
    fail("built with another database (it holds ", FeatureTypeName(db.feature_type()),
         " descriptors of ", db.descriptor_bytes(), " bytes, the vocabulary ",
         FeatureTypeName(vocab.type()), " of ", vocab.row_bytes(), ")");
  }
  if (old) {
    // Versions 1 and 2 (f32 arrays): the index they hold is the one the
    // build makes from the database's descriptors and this vocabulary (both
    // checked); it is made again, in the compact form, rather than read.
    BowIndexOptions options;
    options.direct_level = static_cast<int>(direct_level);
    BowIndex index = Build(std::move(vocabulary), db, options, nullptr, nullptr);
    index.shown_ = shown + " (format version " + std::to_string(version) + ", rebuilt)";
    return index;
  }
  const std::vector<uint32_t> by_rank = DirectNodesByRank(vocab, direct_level);
  if (header.direct_node_bytes != DirectNodeBytes(by_rank.size())) {
    fail("direct entries of ", header.direct_node_bytes, " bytes (", by_rank.size(),
         " nodes to name need ", DirectNodeBytes(by_rank.size()), ")");
  }
  const SectionOffsets at = IndexSections(header, image.size);
  if (at.layout.overflowed() || at.layout.end() != image.size) {
    fail("the file's size (", image.size, " bytes) does not match its ", num_keyframes,
         " keyframes, ", header.keyframe_bytes, " keyframe bytes and ", header.posting_bytes,
         " posting bytes");
  }
  if (!at.layout.PaddingIsZero(image.data)) fail("the padding between sections is not 0");
  if (TablesChecksum(image.data, at, num_keyframes, num_words) != header.tables_checksum)
    fail("tables checksum mismatch (the file is corrupted)");

  // Offsets start at 0, never decrease and end at the total.
  auto check_offsets = [&](const uint64_t* offsets, uint64_t count, uint64_t total,
                           const char* what) {
    if (offsets[0] != 0 || offsets[count] != total)
      fail(what, " offsets do not run from 0 to ", total);
    for (uint64_t i = 0; i < count; ++i) {
      if (offsets[i + 1] < offsets[i]) fail(what, " offsets decrease at ", i);
    }
  };
  // The database: ids in order, feature counts.
  const int32_t* ids = image.At<int32_t>(at.ids);
  const uint64_t* direct_offsets = image.At<uint64_t>(at.direct_offsets);
  check_offsets(direct_offsets, num_keyframes, features, "direct");
  for (uint32_t i = 0; i < num_keyframes; ++i) {
    const int32_t id = db.keyframe(i).id;
    if (ids[i] != id) {
      fail("built with another database (keyframe ", i, " has id ", ids[i], " in the index but ",
           id, " in the database)");
    }
    if (direct_offsets[i + 1] - direct_offsets[i] != db.FeatureCount(i)) {
      fail("built with another database (keyframe ", id, " has ",
           direct_offsets[i + 1] - direct_offsets[i], " feature rows in the index but ",
           db.FeatureCount(i), " in the database)");
    }
  }
  const uint64_t* vector_offsets = image.At<uint64_t>(at.vector_offsets);
  check_offsets(vector_offsets, num_keyframes, entries, "vector");
  const uint64_t* byte_offsets = image.At<uint64_t>(at.keyframe_byte_offsets);
  check_offsets(byte_offsets, num_keyframes, header.keyframe_bytes, "keyframe byte");
  const uint64_t* word_offsets = image.At<uint64_t>(at.word_offsets);
  check_offsets(word_offsets, num_words, entries, "word");
  const uint64_t* word_byte_offsets = image.At<uint64_t>(at.word_byte_offsets);
  check_offsets(word_byte_offsets, num_words, header.posting_bytes, "word byte");
  // The totals divide every posting's weight: finite and > 0 (0 for an
  // empty vector), before any is read.
  const double* totals = image.At<double>(at.totals);
  for (uint32_t i = 0; i < num_keyframes; ++i) {
    const bool empty = vector_offsets[i + 1] == vector_offsets[i];
    if (empty ? totals[i] != 0.0 : !(std::isfinite(totals[i]) && totals[i] > 0.0))
      fail("keyframe ", i, " has total ", totals[i]);
  }

  BowIndex index;
  index.vocabulary_ = std::move(vocabulary);
  index.num_keyframes_ = num_keyframes;
  index.direct_level_ = static_cast<int>(direct_level);
  index.checksum_ = header.header_checksum;
  index.format_version_ = version;
  index.shown_ = shown;
  index.direct_nodes_by_rank_ = by_rank;
  index.direct_node_bytes_ = header.direct_node_bytes;
  index.vector_offsets_ = vector_offsets;
  index.direct_offsets_ = direct_offsets;
  index.keyframe_byte_offsets_ = byte_offsets;
  index.totals_ = totals;
  index.keyframe_bytes_ = image.At<uint8_t>(at.keyframe_bytes);
  index.word_offsets_ = word_offsets;
  index.word_byte_offsets_ = word_byte_offsets;
  index.postings_ = image.At<uint8_t>(at.postings);
  index.posting_bytes_ = header.posting_bytes;
  index.keyframe_sums_ = image.At<uint64_t>(at.keyframe_blocks);
  index.word_sums_ = image.At<uint64_t>(at.word_blocks);
  auto check = std::make_shared<LazyCheck>();
  check->keyframe_checked = std::make_unique<std::atomic<uint8_t>[]>(num_keyframes);
  check->word_checked = std::make_unique<std::atomic<uint8_t>[]>(num_words);
  index.lazy_ = std::move(check);
  index.image_ = std::move(image);
  return index;
}

void BowIndex::CheckInBackground(const std::atomic<bool>& stop) const {
  const Arrays a = MakeArrays();
  const uint32_t num_words = vocabulary_->num_words();
  for (uint32_t w = 0; w < num_words && !stop.load(std::memory_order_relaxed); ++w)
    CheckAndMark(&lazy_->word_checked[w],
                 [&] { return a.WordBlockProblem(w, word_sums_, nullptr); });
  for (uint32_t i = 0; i < num_keyframes_ && !stop.load(std::memory_order_relaxed); ++i)
    CheckAndMark(&lazy_->keyframe_checked[i],
                 [&] { return a.KeyframeBlockProblem(i, keyframe_sums_, nullptr); });
}

bool BowIndex::KeyframeChecked(uint32_t index) const {
  PLACEDB_CHECK(index < num_keyframes_, "keyframe index ", index,
                " is out of range (the index holds ", num_keyframes_, ")");
  return lazy_ == nullptr || lazy_->keyframe_checked[index].load(std::memory_order_acquire) != 0;
}

void BowIndex::VerifyAll() const {
  CheckAllBlocks(MakeArrays(), word_offsets_[vocabulary_->num_words()], keyframe_sums_, word_sums_,
                 shown_, [&] { flat_file::CheckPayloadChecksum(image_, shown_); });
  for (uint32_t i = 0; i < num_keyframes_; ++i)
    lazy_->keyframe_checked[i].store(1, std::memory_order_release);
  for (uint32_t w = 0; w < vocabulary_->num_words(); ++w)
    lazy_->word_checked[w].store(1, std::memory_order_release);
}

BowVector BowIndex::Transform(const DescriptorBlock& query, std::vector<uint32_t>* nodes) const {
  return WeightedVector(*vocabulary_, CountWords(*vocabulary_, direct_level_, query, nodes));
}

BowVector BowIndex::KeyframeVector(uint32_t index) const {
  if (index >= num_keyframes_) {
    PLACEDB_THROW_INVALID("keyframe index ", index, " is out of range (the index holds ",
                          num_keyframes_, ")");
  }
  EnsureKeyframeChecked(index);
  const uint64_t n = vector_offsets_[index + 1] - vector_offsets_[index];
  BowVector v;
  v.words.reserve(n);
  v.weights.reserve(n);
  const double total = totals_[index];
  ReadCheckedEntries(keyframe_bytes_ + keyframe_byte_offsets_[index], n,
                     [&](uint32_t word, uint32_t count) {
                       v.words.push_back(word);
                       v.weights.push_back(EntryWeight(count, vocabulary_->Idf(word), total));
                       return true;
                     });
  return v;
}

std::vector<uint32_t> BowIndex::DirectNodes(uint32_t index) const {
  if (index >= num_keyframes_) {
    PLACEDB_THROW_INVALID("keyframe index ", index, " is out of range (the index holds ",
                          num_keyframes_, ")");
  }
  EnsureKeyframeChecked(index);
  const uint64_t rows = direct_offsets_[index + 1] - direct_offsets_[index];
  const uint8_t* p =
      keyframe_bytes_ + keyframe_byte_offsets_[index + 1] - rows * direct_node_bytes_;
  std::vector<uint32_t> out(rows);
  for (uint64_t r = 0; r < rows; ++r)
    out[r] = direct_nodes_by_rank_[ReadRank(p + r * direct_node_bytes_, direct_node_bytes_)];
  return out;
}

std::vector<BowIndex::Scored> BowIndex::Query(const BowVector& query, size_t max_results,
                                              const std::vector<uint32_t>* among,
                                              const Deadline& deadline, bool* stopped,
                                              const uint8_t* excluded) const {
  const size_t n = query.words.size();
  if (query.weights.size() != n) PLACEDB_THROW_INVALID("a bag of words needs one weight per word");
  const uint32_t num_words = vocabulary_->num_words();
  for (size_t i = 0; i < n; ++i) {
    if (query.words[i] >= num_words || (i > 0 && query.words[i - 1] >= query.words[i])) {
      PLACEDB_THROW_INVALID("the query's words must be ascending and below ", num_words);
    }
  }
  if (among != nullptr) {
    for (size_t i = 0; i < among->size(); ++i) {
      if ((*among)[i] >= num_keyframes_ || (i > 0 && (*among)[i - 1] >= (*among)[i])) {
        PLACEDB_THROW_INVALID("the keyframes to search must be sorted, unique indices below ",
                              num_keyframes_);
      }
    }
  }
  if (max_results == 0 || num_keyframes_ == 0) return {};
  // The postings the query reads, checked (once) before they are read.
  for (size_t i = 0; i < n; ++i) {
    if (query.weights[i] > 0.0f) EnsureWordChecked(query.words[i]);
  }

  thread_local QueryScratch scratch;
  if (scratch.scores.size() < num_keyframes_) {
    scratch.scores.resize(num_keyframes_, 0.0);
    scratch.allowed.resize(num_keyframes_, 0);
    scratch.touched.resize(num_keyframes_ + 1);
  }
  // A contiguous `among` (a partition of contiguous ranges) is walked as a
  // range: each posting list (sorted by keyframe) is decoded up to the
  // range's end, and only the range's postings scored, so that a partition
  // scores its share of the postings, not all of them. The scores are the
  // same.
  const bool range =
      among != nullptr && !among->empty() && among->back() - among->front() + 1 == among->size();
  const uint32_t range_first = range ? among->front() : 0;
  const uint32_t range_end = range ? among->back() + 1 : num_keyframes_;
  const std::vector<uint32_t>* masked = range ? nullptr : among;
  const ScratchReset reset(&scratch, masked);
  // A keyframe's terms are multiplied by mask[k] ^ invert: the among mask
  // (with the excluded ones cleared), or the excluded mask inverted.
  const uint8_t* mask = nullptr;
  uint8_t invert = 0;
  if (masked != nullptr) {
    if (excluded != nullptr) {
      for (const uint32_t k : *among) scratch.allowed[k] = static_cast<uint8_t>(!excluded[k]);
    } else {
      for (const uint32_t k : *among) scratch.allowed[k] = 1;
    }
    mask = scratch.allowed.data();
  } else if (excluded != nullptr) {
    mask = excluded;
    invert = 1;
  }
  double* scores = scratch.scores.data();
  uint32_t* touched = scratch.touched.data();
  size_t& num_touched = scratch.num_touched;
  // Every term is min(q, p) > 0 (stored counts, idfs and totals are > 0; a
  // keyframe outside `among` or excluded gets 0), so a score of 0 means "not
  // touched yet", and each keyframe's terms are added in word order, as
  // BowScore adds them (the min of two floats is exact, so it equals
  // BowScore's min in double; a posting's weight is computed as the
  // keyframe vector's). The additions have no branch: which weight is
  // smaller, and whether a keyframe is new, are coin flips for a branch
  // predictor.
  const bool timed = deadline.enabled();
  const Timer scoring;
  size_t postings_done = 0;
  const auto accumulate = [&](auto with_among) {
    for (size_t i = 0; i < n; ++i) {
      const uint32_t word = query.words[i];
      // Under a deadline, a word is scored only while its postings, at the
      // time per posting so far, still fit before it (not before a keyframe
      // has a score: the query examines at least one).
      // What remains after the word is the selection of the best among the
      // touched keyframes and resetting them: two steps per touched
      // keyframe, each counted like a posting.
      const uint64_t postings = word_offsets_[word + 1] - word_offsets_[word];
      if (timed && num_touched > 0) {
        const double steps = static_cast<double>(3 * postings + 2 * num_touched);
        if (!deadline.Fits(steps * scoring.ElapsedMs() /
                           static_cast<double>(std::max<size_t>(postings_done, 1)))) {
          if (stopped != nullptr) *stopped = true;
          break;
        }
      }
      // The posting lists lie far apart: fetch the offsets of a word 8 ahead
      // and the first postings of a word 4 ahead (its offsets are in cache
      // by now), so that memory latency overlaps the additions.
      if (i + 8 < n) {
        __builtin_prefetch(word_offsets_ + query.words[i + 8]);
        __builtin_prefetch(word_byte_offsets_ + query.words[i + 8]);
      }
      if (i + 4 < n) __builtin_prefetch(postings_ + word_byte_offsets_[query.words[i + 4]]);
      const float q = query.weights[i];
      if (!(q > 0.0f)) continue;
      const uint8_t* p = postings_ + word_byte_offsets_[word];
      size_t done = 0, touched_now = num_touched;
      if (postings > 0) {
        // Each code is read as 4 bytes and masked: the bytes after a code
        // are the next codes or the weights (never the end of the file).
        const uint32_t width = *p;
        const uint8_t* codes = p + 1;
        const uint8_t* weights = codes + postings * width;
        const uint32_t code_mask = width == 4 ? ~0u : (1u << (8 * width)) - 1;
        uint32_t next = 0;
        for (uint64_t j = 0; j < postings; ++j) {
          uint32_t code;
          std::memcpy(&code, codes + j * width, sizeof(code));
          const uint32_t k = next + (code & code_mask);
          next = k + 1;
          if (range) {
            if (k < range_first) continue;
            if (k >= range_end) break;
          }
          ++done;
          float weight;
          std::memcpy(&weight, weights + j * sizeof(float), sizeof(weight));
          float term = std::min(q, weight);
          if constexpr (decltype(with_among)::value) term *= static_cast<float>(mask[k] ^ invert);
          const double before = scores[k];
          touched[touched_now] = k;
          touched_now += static_cast<size_t>((before == 0.0) & (term > 0.0f));
          scores[k] = before + static_cast<double>(term);
        }
      }
      num_touched = touched_now;
      postings_done += done;
    }
  };
  if (mask != nullptr) {
    accumulate(std::true_type());
  } else {
    accumulate(std::false_type());
  }
  // The best max_results of the touched keyframes: one pass with a heap of
  // them, its worst on top, so that most keyframes cost one comparison (at
  // 100 000 keyframes most are touched; copying them all for a selection
  // took milliseconds).
  const auto better = [](const Scored& a, const Scored& b) {
    return a.score > b.score || (a.score == b.score && a.index < b.index);
  };
  std::vector<Scored> out;
  out.reserve(std::min(max_results, num_touched));
  for (size_t i = 0; i < num_touched; ++i) {
    const Scored s{touched[i], scores[touched[i]]};
    if (out.size() < max_results) {
      out.push_back(s);
      std::push_heap(out.begin(), out.end(), better);
    } else if (better(s, out.front())) {
      std::pop_heap(out.begin(), out.end(), better);
      out.back() = s;
      std::push_heap(out.begin(), out.end(), better);
    }
  }
  std::sort(out.begin(), out.end(), better);
  return out;
}

void ResealBowIndex(std::string* bytes) {
  if (bytes->size() < flat_file::kHeaderBytes) return;
  auto header = flat_file::ReadHeader<BowIndexFileHeader>(bytes->data());
  if (header.common.version == kBowIndexFormatVersion) {
    const SectionOffsets at = IndexSections(header, bytes->size());
    if (!at.layout.overflowed() && at.layout.end() <= bytes->size())
      SealBlocks<BowIndex::Arrays>(bytes->data(), at, &header, nullptr);
  }
  flat_file::Reseal(bytes);
}

}  // namespace placedb
