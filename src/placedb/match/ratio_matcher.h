// The match stage: nearest-neighbour matching of a query's descriptors
// against one keyframe's descriptors.
//
// A query descriptor q matches keyframe descriptor t when
//  1. t is q's nearest neighbour in the keyframe and passes Lowe's ratio test
//     (clearly closer than the second nearest) and an absolute distance limit;
//  2. (one_to_one) no other query descriptor is closer to t: many query
//     descriptors cannot pile onto one keyframe descriptor;
//  3. (cross_check) q is also t's nearest neighbour among all of the query's
//     descriptors and passes the ratio test there. This is the guard for sparse
//     keyframes: a keyframe with few descriptors (a small crop, a 1/16 resize)
//     has a distant second neighbour, so its own ratio test lets almost any
//     nearest neighbour through; the query has hundreds of descriptors, so the
//     reverse test keeps its power.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "placedb/feature/types.h"
#include "placedb/match/options.h"

namespace placedb {

// A read-only view of descriptors stored back to back.
struct DescriptorBlock {
  FeatureType type = FeatureType::kOrb;
  const uint8_t* data = nullptr;  // rows * row_bytes bytes
  int rows = 0;
  int row_bytes = 0;  // ORB: 32; SURF: 4 * (64 or 128)
  // SURF only, optional: the sign of the Laplacian of each row, either
  // grouped (the first positive_rows rows +1, the rest -1: a database's rows,
  // scanned by sign without a test per row) or per row (laplacian, +1/-1).
  // Descriptors of opposite signs are never matched (a blob on a dark vs a
  // light background). Neither set: signs unknown, not used.
  int positive_rows = -1;
  const int8_t* laplacian = nullptr;

  const uint8_t* Row(int i) const { return data + static_cast<size_t>(i) * row_bytes; }
};

// A view of a FeatureSet (valid while the set lives). `laplacian` receives
// the keypoints' Laplacian signs for SURF.
DescriptorBlock MakeDescriptorBlock(const FeatureSet& set, std::vector<int8_t>* laplacian);

// SURF: the set reordered (stably) so that keypoints with a positive
// Laplacian (class_id >= 0) come first, and a view of it with positive_rows
// set. Other types: the set as it is, a plain view.
struct GroupedFeatures {
  FeatureSet set;
  DescriptorBlock block;
};
GroupedFeatures GroupByLaplacian(const FeatureSet& set);

// Matches `query` against the descriptors `db` of one keyframe by the rules
// above and returns the number of matches; appends them (queryIdx, trainIdx,
// distance: Hamming bits or L2) to `matches` when given, in query order.
// Throws InvalidArgument when the blocks' types or widths differ.
int MatchDescriptors(const DescriptorBlock& query, const DescriptorBlock& db,
                     const MatchOptions& options, std::vector<cv::DMatch>* matches = nullptr);

// Guided matching (DBoW2's direct index; ORB-SLAM's search by bag of words),
// to rank candidates cheaply: a query row is compared only with the
// keyframe rows of its own label (the vocabulary node both descend
// through), and counts when its nearest among them passes the ratio test
// and the distance limit (and, SURF, has its Laplacian sign). No one-to-one
// rule or cross-check: an estimate of MatchDescriptors' count at a small
// share of its distances.
// The distinct labels of guided matching's query rows, and where each is.
struct GuidedLabels {
  std::vector<uint32_t> distinct;  // ascending
  uint32_t lowest = 0;
  std::vector<int32_t> dense;  // label - lowest -> index in distinct, -1: none (may be empty)
  // Index of `label` in distinct, -1 when the query has no row of it.
  int Find(uint32_t label) const;
};

class GuidedMatcher {
 public:
  // `query` (a view that must outlive this) and one label per row.
  GuidedMatcher(const DescriptorBlock& query, const uint32_t* labels, size_t rows,
                const MatchOptions& options);
  // The count against a keyframe's rows `db` with one label per row.
  // InvalidArgument for a label count other than db.rows, or
  // descriptors of another type or width.
  int Count(const DescriptorBlock& db, const uint32_t* labels, size_t rows) const;

 private:
  DescriptorBlock query_;
  MatchOptions options_;
  GuidedLabels labels_;
  std::vector<uint32_t> begin_;       // label i's rows: order_[begin_[i], begin_[i + 1])
  std::vector<uint32_t> order_;       // query rows by label, then row
  std::vector<uint8_t> sorted_rows_;  // ORB: the query's rows in order_, back to back
};

}  // namespace placedb
