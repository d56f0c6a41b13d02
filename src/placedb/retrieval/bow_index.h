// The bag-of-words index of a database (like DBoW2's database, as flat
// arrays): each keyframe's bag of words, the inverted file (word -> the
// keyframes that have it, with their weights) that scores a query against
// every keyframe by touching only those that share a word with it, and the
// direct index (each feature row's vocabulary node at one level), which
// narrows feature matching to the rows under the same node.
//
// The index file, format version 3 (compact), little-endian, used in place
// from a memory map (nothing is parsed or copied at open):
//
//   header (128 bytes, BowIndexFileHeader; the first 32 are flat_file's CommonHeader)
//     char[8] magic "PLDBBW\r\n"   u32 format version (3)   u32 header bytes (128)
//     u64 file bytes               u64 payload checksum: XXH3-64 of bytes [128, file bytes)
//     32: u64 the vocabulary's checksum (Vocabulary::checksum())
//     40: u32 keyframes K   u32 direct level   u32 vocabulary words W
//     52: u32 direct node bytes D (1, 2 or 4: the width of a direct entry)
//     56: u64 entries P (words over all keyframe vectors = postings)   u64 feature rows F
//     72: u64 XXH3-64 of the tables (ids, vector offsets, direct offsets,
//         keyframe byte offsets, totals, word offsets, word byte offsets,
//         keyframe blocks, word blocks, in that order)
//     80: u64 keyframe bytes B   88: u64 posting bytes Q
//     96: reserved (0) up to the header checksum
//     120: u64 header checksum: XXH3-64 of bytes [0, 120)
//   sections, each at the next multiple of 64 bytes (zero padding between), in this order:
//     ids                   K i32: the database's keyframe ids, in index order
//     vector offsets        K + 1 u64: keyframe i's vector is entries [o[i], o[i + 1])
//     direct offsets        K + 1 u64: keyframe i's rows are direct entries [d[i], d[i + 1])
//     keyframe byte offsets K + 1 u64: keyframe i's block is keyframe bytes [b[i], b[i + 1])
//     totals                K f64: keyframe i's sum of count x idf over its words (0 when
//                           it has none); a word's weight is f32(count x idf / total)
//     keyframe bytes        B bytes: per keyframe, its vector as entries (below), its
//                           words ascending, then its rows' direct entries, D bytes
//                           each: the rank of the row's direct-level node among the
//                           nodes a direct entry may name (the nodes of the direct
//                           level and the leaves above it, in node order)
//     word offsets          W + 1 u64: word w's postings are entries [w[w], w[w + 1])
//     word byte offsets     W + 1 u64: ... and posting bytes [c[w], c[w + 1])
//     postings              Q bytes: per word (nothing for a word without
//                           postings), a width byte b (1 to 4), then each
//                           posting's code in b bytes, little-endian: keyframe
//                           - previous keyframe - 1, keyframes ascending (the
//                           first's "previous" is -1; b is the fewest bytes that
//                           hold every code); then each posting's weight, f32
//     keyframe blocks       K u64: XXH3-64 of keyframe i's block of keyframe bytes
//     word blocks           W u64: XXH3-64 of word w's posting bytes
//   and the file ends with the last section.
// A vector's entry is a word and its count: the LEB128 varint of (word -
// previous word - 1) x 2 + (count > 1) (the first word's "previous" is -1),
// then, when count > 1, the varint of count - 2. A vector's weights are not
// stored: each is computed from its count, the word's idf and the
// keyframe's total, the same double arithmetic as the build's, which also
// made the postings' weights, so a vector read back gives the very weights
// its postings hold (VerifyAll checks it). About 2 bytes a vector entry
// and 5-7 a posting, against 8 and 8 in version 2. The postings keep their
// weight and fixed-width codes because a query reads about a million of
// them at 100 000 keyframes: varints and weights computed per posting
// (measured) made the query's scoring twice as slow.
//
// Versions 1 and 2 (f32 arrays) are still accepted: their header is checked
// (vocabulary, database, direct level) and the index rebuilt in memory
// from the database's descriptors, which gives the same index (it is
// derived from them); saving the database writes version 3.
//
// Integrity: opening checks the header, the section sizes and the tables
// (their checksum, the offsets, the totals, the ids and feature counts
// against the database), not the bytes they index: a keyframe's block is
// checked (block checksum, then every value, its total recomputed) the
// first time it is read, a word's postings the first time a query reads
// them. So no byte influences an answer unchecked, and the open touches a
// few MB at 100 000 keyframes instead of the whole file. VerifyAll checks
// everything now, and that the inverted file is exactly the vectors
// transposed.
#pragma once

#include <atomic>
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
constexpr uint32_t kBowIndexFormatVersion = 3;        // written
constexpr uint32_t kOldestBowIndexFormatVersion = 1;  // still accepted (rebuilt)
struct BowIndexFileHeader {
  flat_file::CommonHeader common;
  uint64_t vocabulary_checksum;
  uint32_t num_keyframes;
  uint32_t direct_level;
  uint32_t num_words;          // the vocabulary's
  uint32_t direct_node_bytes;  // version 3; 0 before
  uint64_t num_entries;
  uint64_t num_features;
  uint64_t tables_checksum;  // version 2 and 3; 0 in version 1
  uint64_t keyframe_bytes;   // version 3; 0 before
  uint64_t posting_bytes;    // version 3; 0 before
  uint64_t reserved[3];      // 0
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
  // it ("Integrity" above): magic, version, sizes, checksums; that it was
  // built with this vocabulary (its checksum) and this database (the
  // keyframe count, every keyframe id in order, every keyframe's feature
  // count); then, on first use, every vector's words ascending and < W,
  // each of idf > 0, with its total; every direct entry the rank of a node
  // of the direct level (or a leaf above it); every posting's keyframe < K,
  // ascending within its word (VerifyAll: and the inverted file exactly the
  // keyframe vectors transposed). A version 1 or 2 file: its header is
  // checked, then the index rebuilt from `db`. Failures are CorruptDatabase
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
  // Checks, on the calling thread, what queries would check on first use
  // of every word (its postings' block: checksum and values), then of
  // every keyframe (its vector and direct entries, which a query reads for
  // each candidate it ranks), in file order, until done or `stop`, so that
  // a session's first queries do not pay for it (PlaceDatabase runs it
  // after the prefetch). It reads the blocks through the mapping, so they
  // are then mapped into the process (resident): every query reads
  // postings all over the section and the blocks of tens of candidates,
  // and a query that maps them itself pays a page fault for each (measured
  // at 100 000 keyframes: the first 25 queries of a session took up to 3x
  // the time of later ones). A damaged block is left unchecked, for the
  // query that reads it to find and report (nothing is thrown here).
  // Thread-safe with queries.
  void CheckInBackground(const std::atomic<bool>& stop) const;
  // Whether keyframe `index`'s block (vector and direct entries) has been
  // checked (by a first use, CheckInBackground or VerifyAll).
  bool KeyframeChecked(uint32_t index) const;
  // Checks everything not yet checked (see "Integrity" above): the payload
  // checksum, every keyframe's and word's block, and the transposition.
  // CorruptDatabase naming the file.
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
  // order of db.Descriptors(index)'s rows.
  std::vector<uint32_t> DirectNodes(uint32_t index) const;

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
  friend void ResealBowIndex(std::string* bytes);
  BowIndex() = default;
  // Checks an image against the vocabulary and database, then points the
  // members into it.
  static BowIndex FromImage(flat_file::Image image, const std::string& shown,
                            std::shared_ptr<const Vocabulary> vocabulary, const Database& db);
  struct Arrays;
  Arrays MakeArrays() const;
  // What checks the blocks on first use (shared by copies).
  struct LazyCheck;
  std::shared_ptr<LazyCheck> lazy_;
  void EnsureKeyframeChecked(uint32_t index) const;
  void EnsureWordChecked(uint32_t word) const;
  std::string shown_;
  uint32_t format_version_ = kBowIndexFormatVersion;
  // The nodes a direct entry may name, by rank (ascending).
  std::vector<uint32_t> direct_nodes_by_rank_;
  uint32_t direct_node_bytes_ = 1;
  const uint64_t* keyframe_sums_ = nullptr;
  const uint64_t* word_sums_ = nullptr;

  flat_file::Image image_;
  std::shared_ptr<const MappedFile> mapping_;
  std::shared_ptr<const Vocabulary> vocabulary_;
  uint32_t num_keyframes_ = 0;
  int direct_level_ = 0;
  uint64_t checksum_ = 0;
  const uint64_t* vector_offsets_ = nullptr;
  const uint64_t* direct_offsets_ = nullptr;
  const uint64_t* keyframe_byte_offsets_ = nullptr;
  const double* totals_ = nullptr;
  const uint8_t* keyframe_bytes_ = nullptr;
  const uint64_t* word_offsets_ = nullptr;
  const uint64_t* word_byte_offsets_ = nullptr;
  const uint8_t* postings_ = nullptr;
  uint64_t posting_bytes_ = 0;
};

// Recomputes the block checksums, the tables checksum (version 2) and the
// flat-file checksums of an index file image, as far as its header and
// sections can be read. For tests that damage a file so that the checks
// themselves, not the checksums, must catch it.
void ResealBowIndex(std::string* bytes);

}  // namespace placedb
