// Which keyframes of a database to open: all, partition i of N (contiguous
// ranges or interleaved), or a list of ids. A ROS worker opens its partition,
// a cluster search its cluster, without decoding the rest of the file.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace placedb {

enum class PartitionScheme {
  kContiguous,   // partition i of N holds indices [n i / N, n (i + 1) / N)
  kInterleaved,  // partition i of N holds the indices with index % N == i
};
const char* PartitionSchemeName(PartitionScheme scheme);
// "contiguous" / "interleaved"; throws InvalidArgument.
PartitionScheme ParsePartitionScheme(const std::string& name);

struct KeyframeSubset {
  enum class Kind { kAll, kPartition, kIds };
  Kind kind = Kind::kAll;
  // kPartition: part in [0, num_parts), num_parts in [1, 4096].
  int part = 0;
  int num_parts = 1;
  PartitionScheme scheme = PartitionScheme::kContiguous;
  // kIds: the keyframe ids to keep (each must be in the database).
  std::vector<int32_t> ids;

  static KeyframeSubset All() { return KeyframeSubset(); }
  static KeyframeSubset Partition(int part, int num_parts,
                                  PartitionScheme scheme = PartitionScheme::kContiguous);
  static KeyframeSubset Ids(std::vector<int32_t> ids);

  bool all() const { return kind == Kind::kAll; }
  std::string Check() const;
  // "all", "partition 2 of 3 (contiguous)", "12 ids".
  std::string Describe() const;
};

// The indices (in file order, ascending) that `subset` keeps of `n`
// keyframes; kIds needs the file's ids, `ids_in_file_order` (size n), and
// throws InvalidArgument naming an id that is not there.
std::vector<size_t> SelectKeyframes(const KeyframeSubset& subset, size_t n,
                                    const std::vector<int32_t>& ids_in_file_order);

// Whether index i of n belongs to partition `part` of `num_parts`.
bool InPartition(size_t i, size_t n, int part, int num_parts, PartitionScheme scheme);

}  // namespace placedb
