// The bag-of-words index of a database (like DBoW2's database, as flat
// arrays): each keyframe's bag of words, the inverted file (word -> the
// keyframes that have it, with their weights) that scores a query against
// every keyframe by touching only those that share a word with it, and the
// direct index (each feature row's vocabulary node at one level), which
// narrows feature matching to the rows under the same node.
//
// The index file, format version 2 (version 1 is read too), little-endian,
// used in place from a memory map (nothing is parsed or copied):
//
//   header (128 bytes, BowIndexFileHeader; the first 32 are flat_file's CommonHeader)
//     char[8] magic "PLDBBW\r\n"   u32 format version (2)   u32 header bytes (128)
//     u64 file bytes               u64 payload checksum: XXH3-64 of bytes [128, file bytes)
//     32: u64 the vocabulary's checksum (Vocabulary::checksum())
//     40: u32 keyframes K   u32 direct level   u32 vocabulary words W   u32 reserved (0)
//     56: u64 entries P (words over all keyframe vectors = postings)   u64 feature rows F
//     72: u64 version 2: XXH3-64 of the tables (ids, vector offsets, direct
//         offsets, word offsets, keyframe blocks, word blocks, in that
//         order); version 1: 0
//     80: reserved (0) up to the header checksum
//     120: u64 header checksum: XXH3-64 of bytes [0, 120)
//   sections, each at the next multiple of 64 bytes (zero padding between), in this order:
//     ids             K i32: the database's keyframe ids, in index order
//     vector offsets  K + 1 u64: keyframe i's vector is entries [o[i], o[i + 1])
//     vector words    P u32, ascending within a keyframe
//     vector weights  P f32, > 0, summing to 1 per keyframe (tf-idf, L1)
//     direct offsets  K + 1 u64: keyframe i's rows are direct entries [d[i], d[i + 1])
//     direct nodes    F u32: each row's node at the direct level (database row order)
//     word offsets    W + 1 u64: word w's postings are [w[w], w[w + 1])
//     postings        P records of 8 bytes: u32 keyframe index (ascending within a
//                     word), f32 weight (the keyframe vector's)
//     keyframe blocks version 2: K u64, keyframe i's XXH3-64 of its vector words,
//                     vector weights and direct nodes (fed in that order)
//     word blocks     version 2: W u64, word w's XXH3-64 of its postings
//   and the file ends with the last section.
//
// Integrity (version 2): opening checks the header, the section sizes and
// the tables (their checksum, the offsets, the ids and feature counts
// against the database), not the arrays they index: a keyframe's vector and
// direct nodes are checked (block checksum, then the values) the first time
// they are read, a word's postings the first time a query reads them. So
// no byte influences an answer unchecked, and the open touches a few MB at
// 100 000 keyframes instead of the whole file. VerifyAll checks everything
// now, and that the inverted file is exactly the vectors transposed (what a
// version 1 file has checked on open).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "placedb/retrieval/options.h"
#include "placedb/retrieval/vocabulary.h"
#include "placedb/storage/database.h"
#include "placedb/util/mapped_file.h"
#include "placedb/util/span.h"
#include "placedb/util/timer.h"

namespace placedb {

class ThreadPool;
class ProgressBar;

// A bag of words: (word, weight) pairs sorted by word, without repeats. The
// vectors made here hold tf-idf weights (a word's count in the image times its
// idf), normalised to L1 norm 1, and only words of weight > 0 (a word in every
// training image has idf 0); an image with no such word has an empty vector.
struct BowVector {
  std::vector<uint32_t> words;
  std::vector<float> weights;

  size_t size() const { return words.size(); }
  bool empty() const { return words.empty(); }
};

// DBoW2's L1 score, in [0, 1] for L1-normalised vectors: 1 - 0.5 |a - b|_1,
// computed as the sum over the words both have of (|a_w| + |b_w| - |a_w - b_w|)
// / 2 (which is min(a_w, b_w) for positive weights), in word order, in double.
// 0 when no word is shared. Both vectors must be sorted by word.
double BowScore(const BowVector& a, const BowVector& b);

// The index file's magic, format version and header (see the top of this
// file).
constexpr char kBowIndexMagic[8] = {'P', 'L', 'D', 'B', 'B', 'W', '\r', '\n'};
constexpr uint32_t kBowIndexFormatVersion = 2;        // written
constexpr uint32_t kOldestBowIndexFormatVersion = 1;  // still read
struct BowIndexFileHeader {
  flat_file::CommonHeader common;
  uint64_t vocabulary_checksum;
  uint32_t num_keyframes;
  uint32_t direct_level;
  uint32_t num_words;  // the vocabulary's
  uint32_t reserved0;  // 0
  uint64_t num_entries;
  uint64_t num_features;
  uint64_t tables_checksum;  // version 2; 0 in version 1
  uint64_t reserved[5];      // 0
  uint64_t header_checksum;
};

void ResealBowIndex(std::string* bytes);

// Immutable once made, copyable and movable (the arrays live in one file
// image, a memory map or memory, that copies share; the vocabulary is
// shared). All members are thread-safe.
class BowIndex {
 public:
  // Transforms every keyframe's descriptors (db.Descriptors(i), i <
  // db.size()) with the vocabulary, and builds the inverted file (keyframe
  // indices ascending in each word's postings) and the direct index.
  // Parallel over keyframes on `pool` (nullptr: this thread); the result does
  // not depend on the number of threads. `progress` (may be nullptr) is
  // advanced by one per keyframe. Throws InvalidArgument for bad
  // options, a direct level deeper than the vocabulary, a database without
  // features, or descriptors of another type or width than the vocabulary's.
  static BowIndex Build(std::shared_ptr<const Vocabulary> vocabulary, const Database& db,
                        const BowIndexOptions& options, ThreadPool* pool, ProgressBar* progress);

  // Writes the index file (layout at the top of this file) crash-safely.
  void Save(const std::string& path) const;
  // Memory-maps an index file and uses its arrays in place, after checking
  // it: magic, version, sizes, checksums; that it was built with this
  // vocabulary (its checksum) and this database (the keyframe count, every
  // keyframe id in order, every keyframe's feature count); every vector's
  // words ascending and < W with finite positive weights summing to 1; every
  // direct node a node of the direct level (or a leaf above it); every
  // posting's keyframe < K, ascending within its word, and the inverted file
  // exactly the keyframe vectors transposed. Failures are CorruptDatabase
  // naming the file (NotFound when there is no file) ("built with another vocabulary", "built with
  // another database", or what is damaged).
  static BowIndex Open(const std::string& path, std::shared_ptr<const Vocabulary> vocabulary,
                       const Database& db);
  // The same on a file mapped by the caller; `shown` names it in errors.
  static BowIndex FromMapped(std::shared_ptr<const MappedFile> file, const std::string& shown,
                             std::shared_ptr<const Vocabulary> vocabulary, const Database& db);

  const Vocabulary& vocabulary() const { return *vocabulary_; }
  const std::shared_ptr<const Vocabulary>& shared_vocabulary() const { return vocabulary_; }
  // Keyframes (the database's, in its order).
  size_t size() const { return num_keyframes_; }
  int direct_level() const { return direct_level_; }
  // The identity of the content (the file's header checksum).
  uint64_t checksum() const { return checksum_; }
  // The file's format version.
  uint32_t format_version() const { return format_version_; }
  // The index file used in place (nullptr: built in memory); for
  // prefetching and releasing its pages (util/mapped_file.h).
  const std::shared_ptr<const MappedFile>& mapped_file() const { return mapping_; }
  // Where the posting lists lie in it: {offset, bytes}. Every query reads
  // some of them, all over the section (the rest of the file is read per
  // candidate keyframe).
  std::pair<uint64_t, uint64_t> PostingsExtent() const;
  // Checks everything not yet checked (see "Integrity" above): the payload
  // checksum, every keyframe's and word's block, and the transposition.
  // CorruptDatabase naming the file; nothing to do for a version 1 file.
  void VerifyAll() const;
  // The bytes of the index file (what Save writes).
  uint64_t file_bytes() const { return image_.size; }

  // The query's bag of words; with `nodes`, also each row's node at the
  // direct level (one per row, in row order). Throws InvalidArgument
  // when the block's type or width is not the vocabulary's.
  BowVector Transform(const DescriptorBlock& query, std::vector<uint32_t>* nodes = nullptr) const;
  // A copy of keyframe `index`'s stored vector (index < size()). These
  // reads, and Query's, check what they read first ("Integrity"):
  // CorruptDatabase when it is damaged.
  BowVector KeyframeVector(uint32_t index) const;
  // The direct-level node of each feature row of keyframe `index`, in the
  // order of db.Descriptors(index)'s rows; a view valid while the index lives.
  Span<uint32_t> DirectNodes(uint32_t index) const;

  struct Scored {
    uint32_t index;  // keyframe index
    double score;    // BowScore with the query
  };
  // The best `max_results` keyframes by BowScore with `query`, best first
  // (ties: the lower index), through the inverted file: only keyframes that
  // share a word with the query are touched, so keyframes of score 0 are
  // never returned. The scores equal BowScore(query, KeyframeVector(index))
  // exactly (the same terms, added in the same order). With `among` (sorted,
  // unique indices < size()), only those keyframes. Query words of weight <= 0
  // score nothing. Throws InvalidArgument for an unsorted query, a word
  // beyond the vocabulary, or a bad `among`.
  //
  // Under `deadline`, once some keyframe has a score, a query word is
  // scored only while its posting list and the selection among the touched
  // keyframes after it, at the time per posting so far, still end before
  // the deadline; else the scoring stops and *stopped (when given) is set:
  // the scores are then those of the query's words scored so far, a partial
  // ranking, so that a query's time budget also bounds this stage.
  // `excluded` (nullptr: none; else one byte per keyframe, 1 = left out: the
  // keyframes removed online) is tested per posting, so removals cost a
  // query nothing else.
  std::vector<Scored> Query(const BowVector& query, size_t max_results,
                            const std::vector<uint32_t>* among = nullptr,
                            const Deadline& deadline = Deadline(), bool* stopped = nullptr,
                            const uint8_t* excluded = nullptr) const;

 private:
  // A posting, the layout of the file's 8-byte record.
  struct Posting {
    uint32_t keyframe;
    float weight;
  };

  friend void ResealBowIndex(std::string* bytes);
  BowIndex() = default;
  // Checks an image against the vocabulary and database, then points the
  // members into it.
  static BowIndex FromImage(flat_file::Image image, const std::string& shown,
                            std::shared_ptr<const Vocabulary> vocabulary, const Database& db);
  struct Arrays;
  Arrays MakeArrays() const;
  // What checks a version 2 file's blocks on first use (shared by copies).
  struct LazyCheck;
  std::shared_ptr<LazyCheck> lazy_;
  void EnsureKeyframeChecked(uint32_t index) const;
  void EnsureWordChecked(uint32_t word) const;
  std::string shown_;
  uint32_t format_version_ = kBowIndexFormatVersion;
  std::vector<uint8_t> direct_node_ok_;  // per vocabulary node: a direct level node
  const uint64_t* keyframe_sums_ = nullptr;
  const uint64_t* word_sums_ = nullptr;

  flat_file::Image image_;
  std::shared_ptr<const MappedFile> mapping_;
  std::shared_ptr<const Vocabulary> vocabulary_;
  uint32_t num_keyframes_ = 0;
  int direct_level_ = 0;
  uint64_t checksum_ = 0;
  const uint64_t* vector_offsets_ = nullptr;
  const uint32_t* vector_words_ = nullptr;
  const float* vector_weights_ = nullptr;
  const uint64_t* direct_offsets_ = nullptr;
  const uint32_t* direct_nodes_ = nullptr;
  const uint64_t* word_offsets_ = nullptr;
  const Posting* postings_ = nullptr;
};

// Recomputes the block checksums, the tables checksum (version 2) and the
// flat-file checksums of an index file image, as far as its header and
// sections can be read. For tests that damage a file so that the checks
// themselves, not the checksums, must catch it.
void ResealBowIndex(std::string* bytes);

}  // namespace placedb
