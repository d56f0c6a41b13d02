#include "placedb/storage/keyframe_subset.h"

#include <algorithm>
#include <unordered_map>

#include "placedb/util/check.h"
#include "placedb/util/options.h"

namespace placedb {

const char* PartitionSchemeName(PartitionScheme scheme) {
  return scheme == PartitionScheme::kInterleaved ? "interleaved" : "contiguous";
}

PartitionScheme ParsePartitionScheme(const std::string& name) {
  if (name == "contiguous") return PartitionScheme::kContiguous;
  if (name == "interleaved") return PartitionScheme::kInterleaved;
  PLACEDB_THROW_INVALID("unknown partition scheme '", name,
                        "' (expected contiguous or interleaved)");
}

KeyframeSubset KeyframeSubset::Partition(int part, int num_parts, PartitionScheme scheme) {
  KeyframeSubset s;
  s.kind = Kind::kPartition;
  s.part = part;
  s.num_parts = num_parts;
  s.scheme = scheme;
  return s;
}

KeyframeSubset KeyframeSubset::Ids(std::vector<int32_t> ids) {
  KeyframeSubset s;
  s.kind = Kind::kIds;
  s.ids = std::move(ids);
  return s;
}

std::string KeyframeSubset::Check() const {
  if (kind == Kind::kPartition) {
    return FirstReason({CheckRange("num_parts", num_parts, 1, 4096),
                        CheckRange("part", part, 0, static_cast<int64_t>(num_parts) - 1)});
  }
  if (kind == Kind::kIds && ids.empty()) return "ids: the id list is empty";
  return "";
}

std::string KeyframeSubset::Describe() const {
  switch (kind) {
    case Kind::kAll:
      return "all";
    case Kind::kPartition:
      return "partition " + std::to_string(part) + " of " + std::to_string(num_parts) + " (" +
             PartitionSchemeName(scheme) + ")";
    case Kind::kIds:
      return std::to_string(ids.size()) + " ids";
  }
  return "?";
}

bool InPartition(size_t i, size_t n, int part, int num_parts, PartitionScheme scheme) {
  const size_t p = static_cast<size_t>(part), np = static_cast<size_t>(num_parts);
  if (scheme == PartitionScheme::kInterleaved) return i % np == p;
  return i >= n * p / np && i < n * (p + 1) / np;
}

std::vector<size_t> SelectKeyframes(const KeyframeSubset& subset, size_t n,
                                    const std::vector<int32_t>& ids_in_file_order) {
  PLACEDB_CHECK_OPTIONS(subset);
  std::vector<size_t> keep;
  switch (subset.kind) {
    case KeyframeSubset::Kind::kAll:
      keep.resize(n);
      for (size_t i = 0; i < n; ++i) keep[i] = i;
      break;
    case KeyframeSubset::Kind::kPartition:
      for (size_t i = 0; i < n; ++i) {
        if (InPartition(i, n, subset.part, subset.num_parts, subset.scheme)) keep.push_back(i);
      }
      break;
    case KeyframeSubset::Kind::kIds: {
      PLACEDB_CHECK(ids_in_file_order.size() == n, "one id per keyframe expected");
      std::unordered_map<int32_t, size_t> index;
      for (size_t i = 0; i < n; ++i) index.emplace(ids_in_file_order[i], i);
      for (const int32_t id : subset.ids) {
        const auto it = index.find(id);
        if (it == index.end()) PLACEDB_THROW_INVALID("keyframe id ", id, " is not in the database");
        keep.push_back(it->second);
      }
      std::sort(keep.begin(), keep.end());
      keep.erase(std::unique(keep.begin(), keep.end()), keep.end());
      break;
    }
  }
  return keep;
}

}  // namespace placedb
