// Nearest-neighbour matching of a query's descriptors against one keyframe's
// descriptors with Lowe's ratio test: a query descriptor matches when its
// nearest neighbour is clearly closer than the second nearest.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "placedb/feature/types.h"

namespace placedb {

// A read-only view of descriptors stored back to back.
struct DescriptorBlock {
  FeatureType type = FeatureType::kOrb;
  const uint8_t* data = nullptr;  // rows * row_bytes bytes
  int rows = 0;
  int row_bytes = 0;  // ORB: 32; SURF: 4 * (64 or 128)
  // SURF only, optional: sign of the Laplacian per row (+1/-1). Descriptors
  // of opposite signs are never matched (a blob on dark vs light background).
  const int8_t* laplacian = nullptr;
};

// A view of a FeatureSet (valid while the set lives). `laplacian` receives
// the keypoints' Laplacian signs for SURF.
DescriptorBlock MakeDescriptorBlock(const FeatureSet& set, std::vector<int8_t>* laplacian);

struct MatchOptions {
  // Lowe's ratio: nearest distance < ratio x second-nearest. (0, 1]. Default 0.8.
  double ratio = 0.8;
  // ORB: a match also needs a Hamming distance of at most this many bits (of
  // 256); 0 disables the limit. Unrelated ORB descriptors lie ~128 bits
  // apart and true matches mostly under 50, so the limit removes the chance
  // matches whose number would otherwise grow with a keyframe's feature
  // count. Default 64.
  int max_hamming = 64;
  // SURF: a match also needs an L2 distance of at most this (descriptors are
  // unit vectors, unrelated ones ~0.5-0.7 apart); 0 disables the limit.
  // Default 0.25 (on data/rtabmap_loop with chroma crops: recall@1 0.86 at
  // 0.25, 0.59 with no limit).
  double max_l2 = 0.25;
  // Use the Laplacian sign to reject SURF candidates early. Default true.
  bool use_laplacian_sign = true;

  std::string Check() const;
};

// Number of query descriptors whose nearest neighbour in `db` passes the
// ratio test (a db block with one row: every nearest neighbour passes).
// Appends the matches (queryIdx, trainIdx, distance) when `matches` is set.
// Throws std::invalid_argument when the blocks' types or widths differ.
int CountRatioMatches(const DescriptorBlock& query, const DescriptorBlock& db,
                      const MatchOptions& options, std::vector<cv::DMatch>* matches = nullptr);

}  // namespace placedb
