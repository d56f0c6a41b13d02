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
                  offsetof(BowIndexFileHeader, num_entries) == 56 &&
                  offsetof(BowIndexFileHeader, header_checksum) ==
                      flat_file::kHeaderChecksumOffset &&
                  sizeof(BowIndexFileHeader) == flat_file::kHeaderBytes,
              "the index header's layout");

constexpr size_t kPostingBytes = 8;

// Where the sections of an index file lie.
struct SectionOffsets {
  explicit SectionOffsets(uint64_t limit) : layout(limit) {}
  flat_file::Layout layout;
  uint64_t ids = 0, vector_offsets = 0, vector_words = 0, vector_weights = 0, direct_offsets = 0,
           direct_nodes = 0, word_offsets = 0, postings = 0, keyframe_blocks = 0, word_blocks = 0;
};
SectionOffsets IndexSections(uint32_t version, uint64_t keyframes, uint64_t entries,
                             uint64_t features, uint64_t words, uint64_t limit) {
  SectionOffsets s(limit);
  flat_file::Layout& layout = s.layout;
  s.ids = layout.Add(keyframes, sizeof(int32_t));
  s.vector_offsets = layout.Add(keyframes + 1, sizeof(uint64_t));
  s.vector_words = layout.Add(entries, sizeof(uint32_t));
  s.vector_weights = layout.Add(entries, sizeof(float));
  s.direct_offsets = layout.Add(keyframes + 1, sizeof(uint64_t));
  s.direct_nodes = layout.Add(features, sizeof(uint32_t));
  s.word_offsets = layout.Add(words + 1, sizeof(uint64_t));
  s.postings = layout.Add(entries, kPostingBytes);
  if (version >= 2) {
    s.keyframe_blocks = layout.Add(keyframes, sizeof(uint64_t));
    s.word_blocks = layout.Add(words, sizeof(uint64_t));
  }
  return s;
}

// One word's term of BowScore: (|a| + |b| - |a - b|) / 2, which is
// min(|a|, |b|) when a and b have the same sign and 0 otherwise (computed so,
// exactly).
double CommonTerm(double a, double b) {
  return a * b > 0.0 ? std::min(std::abs(a), std::abs(b)) : 0.0;
}

// The bag of words of `block`; `nodes` (optional) receives each row's node
// at `direct_level`.
BowVector MakeBowVector(const Vocabulary& vocabulary, int direct_level,
                        const DescriptorBlock& block, std::vector<uint32_t>* nodes) {
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
  // tf-idf: each occurrence adds the word's idf; then L1 normalisation.
  BowVector v;
  std::vector<double> raw;
  double total = 0.0;
  for (size_t i = 0; i < words.size();) {
    size_t end = i;
    while (end < words.size() && words[end] == words[i]) ++end;
    const double weight = static_cast<double>(end - i) * vocabulary.Idf(words[i]);
    if (weight > 0.0) {
      v.words.push_back(words[i]);
      raw.push_back(weight);
      total += weight;
    }
    i = end;
  }
  v.weights.reserve(raw.size());
  for (const double weight : raw) v.weights.push_back(static_cast<float>(weight / total));
  return v;
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
// keyframe's vector and direct nodes, one word's postings (each adds its
// entries' EntryHash to *hash, for the transposition check).
struct BowIndex::Arrays {
  uint32_t num_keyframes = 0, num_words = 0, direct_level = 0;
  const uint64_t* vector_offsets = nullptr;
  const uint32_t* vector_words = nullptr;
  const float* vector_weights = nullptr;
  const uint64_t* direct_offsets = nullptr;
  const uint32_t* direct_nodes = nullptr;
  const uint64_t* word_offsets = nullptr;
  const Posting* postings = nullptr;
  const uint8_t* direct_node_ok = nullptr;  // per vocabulary node
  size_t num_nodes = 0;

  // The arrays of an image whose sections lie at `at` (the node table not
  // set).
  static Arrays At(const char* base, const SectionOffsets& at, uint32_t keyframes, uint32_t words) {
    Arrays a;
    a.num_keyframes = keyframes;
    a.num_words = words;
    a.vector_offsets = reinterpret_cast<const uint64_t*>(base + at.vector_offsets);
    a.vector_words = reinterpret_cast<const uint32_t*>(base + at.vector_words);
    a.vector_weights = reinterpret_cast<const float*>(base + at.vector_weights);
    a.direct_offsets = reinterpret_cast<const uint64_t*>(base + at.direct_offsets);
    a.direct_nodes = reinterpret_cast<const uint32_t*>(base + at.direct_nodes);
    a.word_offsets = reinterpret_cast<const uint64_t*>(base + at.word_offsets);
    a.postings = reinterpret_cast<const Posting*>(base + at.postings);
    return a;
  }

  // Why keyframe i's vector or direct nodes are impossible, or "".
  std::string CheckKeyframe(uint32_t i, uint64_t* hash) const {
    uint64_t h = 0;
    double sum = 0.0;
    for (uint64_t e = vector_offsets[i]; e < vector_offsets[i + 1]; ++e) {
      h += EntryHash(vector_words[e], i, vector_weights[e]);
      if (vector_words[e] >= num_words ||
          (e > vector_offsets[i] && vector_words[e - 1] >= vector_words[e])) {
        return internal::JoinMessage("keyframe ", i, "'s words are not ascending and below ",
                                     num_words);
      }
      if (!(std::isfinite(vector_weights[e]) && vector_weights[e] > 0.0f))
        return internal::JoinMessage("keyframe ", i, " has weight ", vector_weights[e],
                                     " (finite and > 0 expected)");
      sum += vector_weights[e];
    }
    if (vector_offsets[i + 1] > vector_offsets[i] && std::abs(sum - 1.0) > 1e-3)
      return internal::JoinMessage("keyframe ", i, "'s weights sum to ", sum, ", not 1");
    for (uint64_t e = direct_offsets[i]; e < direct_offsets[i + 1]; ++e) {
      const uint32_t node = direct_nodes[e];
      if (node >= num_nodes || !direct_node_ok[node])
        return internal::JoinMessage("direct entry ", e, " (node ", node,
                                     ") is not a node of level ", direct_level);
    }
    if (hash != nullptr) *hash += h;
    return "";
  }
  // Why word w's postings are impossible, or "".
  std::string CheckWord(uint32_t word, uint64_t* hash) const {
    uint64_t h = 0;
    for (uint64_t p = word_offsets[word]; p < word_offsets[word + 1]; ++p) {
      const uint32_t k = postings[p].keyframe;
      if (k >= num_keyframes)
        return internal::JoinMessage("a posting of word ", word, " names keyframe ", k);
      if (p > word_offsets[word] && postings[p - 1].keyframe >= k)
        return internal::JoinMessage("the postings of word ", word, " are not sorted by keyframe");
      if (!(std::isfinite(postings[p].weight) && postings[p].weight > 0.0f))
        return internal::JoinMessage("a posting of word ", word, " has weight ", postings[p].weight,
                                     " (finite and > 0 expected)");
      h += EntryHash(word, k, postings[p].weight);
    }
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
  // The block checksums of version 2.
  uint64_t KeyframeSum(uint32_t i) const {
    Checksum64Stream s;
    const uint64_t b = vector_offsets[i], e = vector_offsets[i + 1];
    s.Update(vector_words + b, (e - b) * sizeof(uint32_t));
    s.Update(vector_weights + b, (e - b) * sizeof(float));
    s.Update(direct_nodes + direct_offsets[i],
             (direct_offsets[i + 1] - direct_offsets[i]) * sizeof(uint32_t));
    return s.Digest();
  }
  uint64_t WordSum(uint32_t word) const {
    return Checksum64(postings + word_offsets[word],
                      (word_offsets[word + 1] - word_offsets[word]) * kPostingBytes);
  }
};

struct BowIndex::LazyCheck {
  std::unique_ptr<std::atomic<uint8_t>[]> keyframe_checked, word_checked;
};

BowIndex::Arrays BowIndex::MakeArrays() const {
  Arrays a;
  a.num_keyframes = num_keyframes_;
  a.num_words = vocabulary_->num_words();
  a.direct_level = static_cast<uint32_t>(direct_level_);
  a.vector_offsets = vector_offsets_;
  a.vector_words = vector_words_;
  a.vector_weights = vector_weights_;
  a.direct_offsets = direct_offsets_;
  a.direct_nodes = direct_nodes_;
  a.word_offsets = word_offsets_;
  a.postings = postings_;
  a.direct_node_ok = direct_node_ok_.data();
  a.num_nodes = direct_node_ok_.size();
  return a;
}

namespace {

// Marks a block checked once `problem` finds nothing wrong with it (else
// CorruptDatabase "<shown>: <problem>").
template <typename Problem>
void CheckOnce(std::atomic<uint8_t>* checked, const std::string& shown, const Problem& problem) {
  if (checked->load(std::memory_order_acquire)) return;
  const std::string bad = problem();
  if (!bad.empty()) PLACEDB_THROW_CORRUPT(shown, ": ", bad);
  checked->store(1, std::memory_order_release);
}

}  // namespace

void BowIndex::EnsureKeyframeChecked(uint32_t index) const {
  if (lazy_ == nullptr) return;
  CheckOnce(&lazy_->keyframe_checked[index], shown_,
            [&] { return MakeArrays().KeyframeBlockProblem(index, keyframe_sums_, nullptr); });
}

void BowIndex::EnsureWordChecked(uint32_t word) const {
  if (lazy_ == nullptr) return;
  CheckOnce(&lazy_->word_checked[word], shown_,
            [&] { return MakeArrays().WordBlockProblem(word, word_sums_, nullptr); });
}

namespace {

// Everything of an index's arrays: every keyframe's and word's block (and,
// with `sums`, its block checksum), and the inverted file exactly the
// vectors transposed. Halves of the vectors and of the postings (split
// where half the entries lie) and `also` run at once. Throws
// CorruptDatabase "<shown>: ...".
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

// The XXH3-64 of a version 2 file's tables (BowIndexFileHeader::tables_checksum).
uint64_t TablesChecksum(const char* data, const SectionOffsets& at, uint64_t keyframes,
                        uint64_t words) {
  Checksum64Stream s;
  s.Update(data + at.ids, keyframes * sizeof(int32_t));
  s.Update(data + at.vector_offsets, (keyframes + 1) * sizeof(uint64_t));
  s.Update(data + at.direct_offsets, (keyframes + 1) * sizeof(uint64_t));
  s.Update(data + at.word_offsets, (words + 1) * sizeof(uint64_t));
  s.Update(data + at.keyframe_blocks, keyframes * sizeof(uint64_t));
  s.Update(data + at.word_blocks, words * sizeof(uint64_t));
  return s.Digest();
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
  std::vector<BowVector> vectors(num_keyframes);
  std::vector<std::vector<uint32_t>> nodes(num_keyframes);
  const auto transform = [&](size_t i) {
    vectors[i] = MakeBowVector(*vocabulary, options.direct_level, db.Descriptors(i), &nodes[i]);
    if (progress != nullptr) progress->Advance(1);
  };
  ForEach(pool, num_keyframes, transform);
  uint64_t entries = 0, features = 0;
  for (size_t i = 0; i < num_keyframes; ++i) {
    entries += vectors[i].size();
    features += nodes[i].size();
  }
  const uint32_t num_words = vocabulary->num_words();
  const SectionOffsets at = IndexSections(kBowIndexFormatVersion, num_keyframes, entries, features,
                                          num_words, UINT64_MAX / 4);
  char* w = nullptr;
  flat_file::Image image = flat_file::NewImage(at.layout.end(), &w);
  BowIndexFileHeader header{};
  header.vocabulary_checksum = vocabulary->checksum();
  header.num_keyframes = static_cast<uint32_t>(num_keyframes);
  header.direct_level = static_cast<uint32_t>(options.direct_level);
  header.num_words = num_words;
  header.num_entries = entries;
  header.num_features = features;
  std::memcpy(w, &header, sizeof(header));

  auto* ids = reinterpret_cast<int32_t*>(w + at.ids);
  auto* vector_offsets = reinterpret_cast<uint64_t*>(w + at.vector_offsets);
  auto* vector_words = reinterpret_cast<uint32_t*>(w + at.vector_words);
  auto* vector_weights = reinterpret_cast<float*>(w + at.vector_weights);
  auto* direct_offsets = reinterpret_cast<uint64_t*>(w + at.direct_offsets);
  auto* direct_nodes = reinterpret_cast<uint32_t*>(w + at.direct_nodes);
  auto* word_offsets = reinterpret_cast<uint64_t*>(w + at.word_offsets);
  auto* postings = reinterpret_cast<Posting*>(w + at.postings);
  uint64_t entry = 0, row = 0;
  for (size_t i = 0; i < num_keyframes; ++i) {
    ids[i] = db.keyframe(i).id;
    vector_offsets[i] = entry;
    direct_offsets[i] = row;
    std::copy(vectors[i].words.begin(), vectors[i].words.end(), vector_words + entry);
    std::copy(vectors[i].weights.begin(), vectors[i].weights.end(), vector_weights + entry);
    std::copy(nodes[i].begin(), nodes[i].end(), direct_nodes + row);
    for (const uint32_t word : vectors[i].words) ++word_offsets[word + 1];
    entry += vectors[i].size();
    row += nodes[i].size();
  }
  vector_offsets[num_keyframes] = entry;
  direct_offsets[num_keyframes] = row;
  // The inverted file: word_offsets[w] counts word w's postings, then is
  // its start; filling advances it to its end (the next word's start), which
  // a shift by one undoes. Keyframes are visited in order, so each word's
  // postings come out sorted by keyframe.
  for (uint32_t word = 0; word < num_words; ++word) word_offsets[word + 1] += word_offsets[word];
  for (size_t i = 0; i < num_keyframes; ++i) {
    for (size_t e = 0; e < vectors[i].size(); ++e) {
      postings[word_offsets[vectors[i].words[e]]++] =
          Posting{static_cast<uint32_t>(i), vectors[i].weights[e]};
    }
  }
  for (uint32_t word = num_words; word > 0; --word) word_offsets[word] = word_offsets[word - 1];
  word_offsets[0] = 0;
  // The block checksums, then the tables', in the header.
  const Arrays a = Arrays::At(w, at, static_cast<uint32_t>(num_keyframes), num_words);
  auto* keyframe_sums = reinterpret_cast<uint64_t*>(w + at.keyframe_blocks);
  auto* word_sums = reinterpret_cast<uint64_t*>(w + at.word_blocks);
  ForEach(pool, num_keyframes,
          [&](size_t i) { keyframe_sums[i] = a.KeyframeSum(static_cast<uint32_t>(i)); });
  ForEach(pool, num_words,
          [&](size_t word) { word_sums[word] = a.WordSum(static_cast<uint32_t>(word)); });
  header.tables_checksum = TablesChecksum(w, at, num_keyframes, num_words);
  std::memcpy(w, &header, sizeof(header));
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
          word_offsets_[vocabulary_->num_words()] * sizeof(Posting)};
}

BowIndex BowIndex::FromMapped(std::shared_ptr<const MappedFile> file, const std::string& shown,
                              std::shared_ptr<const Vocabulary> vocabulary, const Database& db) {
  BowIndex index = FromImage(flat_file::MapImage(file), shown, std::move(vocabulary), db);
  index.mapping_ = std::move(file);
  return index;
}

BowIndex BowIndex::FromImage(flat_file::Image image, const std::string& shown,
                             std::shared_ptr<const Vocabulary> vocabulary, const Database& db) {
  static_assert(std::is_standard_layout<Posting>::value && sizeof(Posting) == kPostingBytes,
                "Posting is the 8-byte posting record");
  PLACEDB_CHECK(vocabulary != nullptr, "a bag-of-words index needs a vocabulary");
  if (!HostIsLittleEndian()) PLACEDB_THROW_IO("placedb indexes need a little-endian host");
  auto fail = [&](const auto&... what) { PLACEDB_THROW_CORRUPT(shown, ": ", what...); };
  // Version 1 is read too: the header check is for the version it says.
  uint32_t version = kBowIndexFormatVersion;
  if (image.size >= flat_file::kHeaderBytes) {
    const uint32_t said = flat_file::ReadHeader<BowIndexFileHeader>(image.data).common.version;
    if (said >= kOldestBowIndexFormatVersion && said <= kBowIndexFormatVersion) version = said;
  }
  const bool lazy = version >= 2;
  // The payload's checksum: version 1 checks it below, beside the checks
  // that read the payload (all of them bounded by the header, which is
  // checked here); version 2 per block, on first use.
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
  if (header.reserved0 != 0 || (!lazy && header.tables_checksum != 0) ||
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
  const SectionOffsets at =
      IndexSections(version, num_keyframes, entries, features, num_words, image.size);
  if (at.layout.overflowed() || at.layout.end() != image.size) {
    fail("the file's size (", image.size, " bytes) does not match its ", num_keyframes,
         " keyframes, ", entries, " entries and ", features, " feature rows");
  }
  if (!at.layout.PaddingIsZero(image.data)) fail("the padding between sections is not 0");
  if (lazy && TablesChecksum(image.data, at, num_keyframes, num_words) != header.tables_checksum)
    fail("tables checksum mismatch (the file is corrupted)");

  // The database: ids in order, feature counts.
  const int32_t* ids = image.At<int32_t>(at.ids);
  const uint64_t* direct_offsets = image.At<uint64_t>(at.direct_offsets);
  // Offsets start at 0, never decrease and end at the total.
  auto check_offsets = [&](const uint64_t* offsets, uint64_t count, uint64_t total,
                           const char* what) {
    if (offsets[0] != 0 || offsets[count] != total)
      fail(what, " offsets do not run from 0 to ", total);
    for (uint64_t i = 0; i < count; ++i) {
      if (offsets[i + 1] < offsets[i]) fail(what, " offsets decrease at ", i);
    }
  };
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
  const uint64_t* word_offsets = image.At<uint64_t>(at.word_offsets);
  check_offsets(word_offsets, num_words, entries, "word");

  BowIndex index;
  index.vocabulary_ = std::move(vocabulary);
  index.num_keyframes_ = num_keyframes;
  index.direct_level_ = static_cast<int>(direct_level);
  index.checksum_ = header.header_checksum;
  index.format_version_ = version;
  index.shown_ = shown;
  index.vector_offsets_ = vector_offsets;
  index.vector_words_ = image.At<uint32_t>(at.vector_words);
  index.vector_weights_ = image.At<float>(at.vector_weights);
  index.direct_offsets_ = direct_offsets;
  index.direct_nodes_ = image.At<uint32_t>(at.direct_nodes);
  index.word_offsets_ = word_offsets;
  index.postings_ = image.At<Posting>(at.postings);
  // Which nodes a direct entry may name, as a table of one byte per node:
  // the entries are then checked in one sequential pass instead of one
  // random access into the tree each.
  index.direct_node_ok_.assign(vocab.num_nodes(), 0);
  for (uint32_t node = 0; node < vocab.num_nodes(); ++node) {
    const Vocabulary::Node& n = vocab.node(node);
    index.direct_node_ok_[node] =
        n.level == direct_level || (n.num_children == 0 && n.level < direct_level);
  }
  if (lazy) {
    index.keyframe_sums_ = image.At<uint64_t>(at.keyframe_blocks);
    index.word_sums_ = image.At<uint64_t>(at.word_blocks);
    auto check = std::make_shared<LazyCheck>();
    check->keyframe_checked = std::make_unique<std::atomic<uint8_t>[]>(num_keyframes);
    check->word_checked = std::make_unique<std::atomic<uint8_t>[]>(num_words);
    index.lazy_ = std::move(check);
  } else {
    // Version 1: everything now, with the payload's checksum (whose failure
    // is reported first).
    CheckAllBlocks(index.MakeArrays(), entries, nullptr, nullptr, shown,
                   [&] { flat_file::CheckPayloadChecksum(image, shown); });
  }
  index.image_ = std::move(image);
  return index;
}

void BowIndex::VerifyAll() const {
  if (lazy_ == nullptr) return;
  CheckAllBlocks(MakeArrays(), word_offsets_[vocabulary_->num_words()], keyframe_sums_, word_sums_,
                 shown_, [&] { flat_file::CheckPayloadChecksum(image_, shown_); });
  for (uint32_t i = 0; i < num_keyframes_; ++i)
    lazy_->keyframe_checked[i].store(1, std::memory_order_release);
  for (uint32_t w = 0; w < vocabulary_->num_words(); ++w)
    lazy_->word_checked[w].store(1, std::memory_order_release);
}

BowVector BowIndex::Transform(const DescriptorBlock& query, std::vector<uint32_t>* nodes) const {
  return MakeBowVector(*vocabulary_, direct_level_, query, nodes);
}

BowVector BowIndex::KeyframeVector(uint32_t index) const {
  if (index >= num_keyframes_) {
    PLACEDB_THROW_INVALID("keyframe index ", index, " is out of range (the index holds ",
                          num_keyframes_, ")");
  }
  EnsureKeyframeChecked(index);
  const uint64_t begin = vector_offsets_[index], end = vector_offsets_[index + 1];
  BowVector v;
  v.words.assign(vector_words_ + begin, vector_words_ + end);
  v.weights.assign(vector_weights_ + begin, vector_weights_ + end);
  return v;
}

Span<uint32_t> BowIndex::DirectNodes(uint32_t index) const {
  if (index >= num_keyframes_) {
    PLACEDB_THROW_INVALID("keyframe index ", index, " is out of range (the index holds ",
                          num_keyframes_, ")");
  }
  EnsureKeyframeChecked(index);
  const uint64_t begin = direct_offsets_[index];
  return Span<uint32_t>(direct_nodes_ + begin,
                        static_cast<size_t>(direct_offsets_[index + 1] - begin));
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
  if (lazy_ != nullptr) {
    for (size_t i = 0; i < n; ++i) {
      if (query.weights[i] > 0.0f) EnsureWordChecked(query.words[i]);
    }
  }

  thread_local QueryScratch scratch;
  if (scratch.scores.size() < num_keyframes_) {
    scratch.scores.resize(num_keyframes_, 0.0);
    scratch.allowed.resize(num_keyframes_, 0);
    scratch.touched.resize(num_keyframes_ + 1);
  }
  // A contiguous `among` (a partition of contiguous ranges) is walked as a
  // range: each posting list (sorted by keyframe) from the range's first
  // keyframe to its end, so that a partition reads its share of the
  // postings, not all of them. The scores are the same.
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
  // Every term is min(q, p) > 0 (stored weights are > 0; a keyframe outside
  // `among` or excluded gets 0), so a score of 0 means "not touched yet", and each
  // keyframe's terms are added in word order, as BowScore adds them (the
  // min of two floats is exact, so it equals BowScore's min in double). The
  // inner loop has no branch: which weight is smaller, and whether a
  // keyframe is new, are coin flips for a branch predictor.
  const bool timed = deadline.enabled();
  const Timer scoring;
  size_t postings_done = 0;
  const auto accumulate = [&](auto with_among) {
    for (size_t i = 0; i < n; ++i) {
      // Under a deadline, a word is scored only while its postings, at the
      // time per posting so far, still fit before it (not before a keyframe
      // has a score: the query examines at least one).
      // What remains after the word is the selection of the best among the
      // touched keyframes and resetting them: two steps per touched
      // keyframe, each counted like a posting (measured: 1.4 ns for a
      // selection step, 2.6 ns per posting, at 100 000 keyframes).
      if (timed && num_touched > 0) {
        const uint64_t postings = word_offsets_[query.words[i] + 1] - word_offsets_[query.words[i]];
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
      if (i + 8 < n) __builtin_prefetch(word_offsets_ + query.words[i + 8]);
      if (i + 4 < n) __builtin_prefetch(postings_ + word_offsets_[query.words[i + 4]]);
      const float q = query.weights[i];
      if (!(q > 0.0f)) continue;
      const Posting* p = postings_ + word_offsets_[query.words[i]];
      const Posting* end = postings_ + word_offsets_[query.words[i] + 1];
      if (range) {
        const auto before_first = [](const Posting& x, uint32_t k) { return x.keyframe < k; };
        p = std::lower_bound(p, end, range_first, before_first);
        end = std::lower_bound(p, end, range_end, before_first);
      }
      postings_done += static_cast<size_t>(end - p);
      for (; p != end; ++p) {
        const uint32_t k = p->keyframe;
        float term = std::min(q, p->weight);
        if constexpr (decltype(with_among)::value) term *= static_cast<float>(mask[k] ^ invert);
        const double before = scores[k];
        touched[num_touched] = k;
        num_touched += static_cast<size_t>((before == 0.0) & (term > 0.0f));
        scores[k] = before + static_cast<double>(term);
      }
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
  if (header.common.version >= 2) {
    const SectionOffsets at =
        IndexSections(header.common.version, header.num_keyframes, header.num_entries,
                      header.num_features, header.num_words, bytes->size());
    if (!at.layout.overflowed() && at.layout.end() <= bytes->size()) {
      char* w = bytes->data();
      const BowIndex::Arrays a =
          BowIndex::Arrays::At(w, at, header.num_keyframes, header.num_words);
      auto* keyframe_sums = reinterpret_cast<uint64_t*>(w + at.keyframe_blocks);
      auto* word_sums = reinterpret_cast<uint64_t*>(w + at.word_blocks);
      const auto inside = [](uint64_t begin, uint64_t end, uint64_t total) {
        return begin <= end && end <= total;
      };
      // Only the blocks whose offsets lie inside their arrays.
      for (uint32_t i = 0; i < a.num_keyframes; ++i) {
        if (inside(a.vector_offsets[i], a.vector_offsets[i + 1], header.num_entries) &&
            inside(a.direct_offsets[i], a.direct_offsets[i + 1], header.num_features)) {
          keyframe_sums[i] = a.KeyframeSum(i);
        }
      }
      for (uint32_t word = 0; word < a.num_words; ++word) {
        if (inside(a.word_offsets[word], a.word_offsets[word + 1], header.num_entries))
          word_sums[word] = a.WordSum(word);
      }
      header.tables_checksum = TablesChecksum(w, at, header.num_keyframes, header.num_words);
      std::memcpy(w, &header, sizeof(header));
    }
  }
  flat_file::Reseal(bytes);
}

}  // namespace placedb
