// The bag-of-words vocabulary: a tree of descriptor clusters (hierarchical
// k-means, as in DBoW2) whose leaves are the words, with an IDF weight per
// word. Its file is a flat file (storage/flat_file.h), as is the
// bag-of-words index's (bow_index.h).
//
// The vocabulary file, format version 1, little-endian, used in place from a
// memory map (nothing is parsed or copied):
//
//   header (128 bytes, VocabularyFileHeader; the first 32 are flat_file's CommonHeader)
//     char[8] magic "PLDBVO\r\n"   u32 format version (1)   u32 header bytes (128)
//     u64 file bytes               u64 payload checksum: XXH3-64 of bytes [128, file bytes)
//     32: u32 feature type (1 ORB, 2 SURF)   u32 row bytes (ORB 32; SURF 256 or 512)
//     40: u32 branching   u32 depth   u32 nodes N   u32 words W
//     56: u32 training iterations   u32 reserved (0)   u64 training seed
//     72: u64 training rows (the sample)   u64 documents (the blocks the IDF counts)
//     88: reserved (0) up to the header checksum
//     120: u64 header checksum: XXH3-64 of bytes [0, 120), which hold the payload
//          checksum, so it identifies the whole content (Vocabulary::checksum())
//   sections, each at the next multiple of 64 bytes (zero padding between), in this order:
//     nodes      N records of 16 bytes (Vocabulary::Node)
//     centroids  N rows of row bytes (the root's is all zero); ORB bits, SURF f32
//     idf        W f32, each finite and >= 0
//   and the file ends with the idf section.
//
// The tree: node 0 is the root, at level 0. The children of a node are the
// nodes [first child, first child + children), listed breadth first (the
// children of node i directly follow those of the internal nodes before i),
// so every child has a larger index than its parent and every node but the
// root has exactly one parent. An internal node has 2 to branching children
// and no word; a leaf has none, first child 0 and a word: words number the
// leaves 0, 1, ... in node order. A child's level is its parent's plus one, at
// most depth. Open checks all of it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "placedb/feature/types.h"
#include "placedb/match/ratio_matcher.h"
#include "placedb/storage/flat_file.h"
#include "placedb/util/mapped_file.h"
#include "placedb/retrieval/options.h"

namespace placedb {

class ThreadPool;
class ProgressBar;

// The vocabulary file's header (see the top of this file).
struct VocabularyFileHeader {
  flat_file::CommonHeader common;
  uint32_t feature_type;  // FeatureType: 1 ORB, 2 SURF
  uint32_t row_bytes;
  uint32_t branching;
  uint32_t depth;
  uint32_t num_nodes;
  uint32_t num_words;
  uint32_t iterations;  // the training parameters, for the record
  uint32_t reserved0;   // 0
  uint64_t seed;
  uint64_t training_rows;
  uint64_t documents;
  uint64_t reserved[4];  // 0
  uint64_t header_checksum;
};

// The vocabulary file's magic and format version.
constexpr char kVocabularyMagic[8] = {'P', 'L', 'D', 'B', 'V', 'O', '\r', '\n'};
constexpr uint32_t kVocabularyFormatVersion = 1;

// A vocabulary tree. Immutable once made, cheap to share
// (std::shared_ptr<const Vocabulary>), copyable and movable: the arrays live
// in one file image (a memory map or, after Train, memory) that copies share.
// All const members are thread-safe.
class Vocabulary {
 public:
  // A node of the tree: the layout of the file's node record, used in place.
  struct Node {
    uint32_t first_child;   // the first of the contiguous children; 0 for a leaf
    uint32_t num_children;  // 0 for a leaf, else 2 to branching
    uint32_t word;          // a leaf's word id; kNoWord for an internal node
    uint32_t level;         // 0 for the root, the parent's + 1 below
  };
  static constexpr uint32_t kNoWord = UINT32_MAX;

  // Hierarchical clustering of the rows of `blocks` (one type and width for
  // all: ORB 32-byte rows, or SURF rows of 64 or 128 floats; SURF's Laplacian
  // signs are not used). From the root down, each node's rows are split into
  // `branching` clusters, seeded k-means++-style (the first centre uniformly,
  // each next one with probability proportional to the squared distance to
  // the nearest centre so far), then refined for `iterations` rounds:
  //   ORB:  k-majority, Hamming distance; a centroid bit is 1 where more than
  //         half of the cluster's rows have it (ties: 0);
  //   SURF: k-means, L2 distance; a centroid is the mean of its rows.
  // A cluster left empty keeps its centre and is dropped at the end. A node
  // becomes a leaf when it is at `depth`, has fewer rows than branching, or
  // splits into fewer than two clusters (e.g. all its rows are equal).
  // Distances are the ones Word() uses (match/hamming.h, match/l2_distance.h).
  //
  // The IDF weight of a word is log(N / n): N is the number of blocks, each
  // block one document (image), and n the number of blocks with a row whose
  // Word() it is (n = 0: log(N), as rare as can be).
  //
  // Seeded (options.seed) and reproducible: the result is bit-identical for
  // any number of threads of `pool` (nullptr: this thread only). Rows are
  // assigned to centres in parallel (each row on its own), each centroid is
  // summed in row order by one task, sibling nodes are clustered in parallel
  // and numbered in parent order. (Across machines, SURF vocabularies may
  // differ: the L2 kernel the CPU runs rounds in its own order.) `progress`
  // (may be nullptr) is advanced by TrainingWork() units in all; give the
  // bar that total.
  // Throws InvalidArgument for bad options, no rows, blocks of
  // different types or widths, a width the type cannot have, or SURF rows
  // that are not finite.
  static Vocabulary Train(const std::vector<DescriptorBlock>& blocks,
                          const VocabularyOptions& options, ThreadPool* pool,
                          ProgressBar* progress);
  // The units Train advances its progress bar by: (sampled rows) x depth, as
  // nodes finish (a node's rows, and a leaf's rows times the levels left
  // below it), then one per block as the IDF counts it.
  static uint64_t TrainingWork(const std::vector<DescriptorBlock>& blocks,
                               const VocabularyOptions& options);

  // Writes the vocabulary file (layout at the top of this file) crash-safely.
  void Save(const std::string& path) const;
  // Memory-maps a vocabulary file and uses its arrays in place, after
  // checking everything (milliseconds for a million words; the checksums run
  // at tens of GB/s): magic, version, sizes, checksums, the parameters, the
  // tree (children in range and breadth first, so acyclic; levels; children
  // counts), dense word ids, finite non-negative idf, finite SURF centroids.
  // Any failure is CorruptDatabase naming the file and what is wrong
  // (NotFound when there is no file, IoError when it cannot be read).
  static Vocabulary Open(const std::string& path);
  // The same on a file mapped by the caller; `shown_name` names it in errors.
  static Vocabulary FromMapped(std::shared_ptr<const MappedFile> file,
                               const std::string& shown_name);

  FeatureType type() const { return type_; }
  int row_bytes() const { return row_bytes_; }
  uint32_t num_words() const { return num_words_; }
  uint32_t num_nodes() const { return num_nodes_; }
  int depth() const { return depth_; }
  int branching() const { return branching_; }
  // The identity of the content (the file's header checksum): indexes record
  // it to refer to their vocabulary.
  uint64_t checksum() const { return checksum_; }
  // The bytes of the vocabulary file (what Save writes).
  uint64_t file_bytes() const { return image_.size; }

  // The word (leaf) of a descriptor row of row_bytes() bytes: from the root,
  // descend to the closest child at each level (ties: the lower child; a row
  // with NaN distances to every child takes the first). When `node_level` >= 0
  // and `node` is given, *node receives the node passed at that level (levels
  // counted from the root = 0), or the leaf when the leaf is above that
  // level: the direct index's node.
  uint32_t Word(const uint8_t* row, int node_level = -1, uint32_t* node = nullptr) const;
  // Word() of `count` rows stored back to back: words[i] (and, with `nodes`
  // and node_level >= 0, nodes[i]) for row i. The rows descend together,
  // level by level, each prefetching the children it compares with next, so
  // that the tree's cache misses overlap instead of following one another.
  // Word() is this for one row.
  void Words(const uint8_t* rows, int count, int node_level, uint32_t* words,
             uint32_t* nodes) const;
  // The IDF weight of `word` (< num_words()).
  float Idf(uint32_t word) const { return idf_[word]; }

  // The tree, for tools and tests: node `index` (< num_nodes()) and its
  // centroid row (row_bytes() bytes).
  const Node& node(uint32_t index) const { return nodes_[index]; }
  const uint8_t* Centroid(uint32_t index) const {
    return centroids_ + static_cast<size_t>(index) * row_bytes_;
  }

 private:
  Vocabulary() = default;
  // Points the members into an image whose header is trusted (Train's own,
  // or one FromImage has checked).
  void Bind(flat_file::Image image);
  static Vocabulary FromImage(flat_file::Image image, const std::string& shown);

  flat_file::Image image_;
  FeatureType type_ = FeatureType::kOrb;
  int row_bytes_ = 0;
  int branching_ = 0;
  int depth_ = 0;
  uint32_t num_nodes_ = 0;
  uint32_t num_words_ = 0;
  uint64_t checksum_ = 0;
  const Node* nodes_ = nullptr;
  const uint8_t* centroids_ = nullptr;
  const float* idf_ = nullptr;
};

}  // namespace placedb
