// The options of the match and verify stages (part of the public face,
// placedb/placedb.h; the stages are match/ratio_matcher.h and
// match/geometric_verification.h).
#pragma once

#include <string>

#include "placedb/util/option_table.h"

namespace placedb {

struct MatchOptions {
  // Lowe's ratio: nearest distance < ratio x second-nearest. Range (0, 1].
  // Default 0.8.
  double ratio = 0.8;
  // ORB: a match also needs a Hamming distance of at most this many bits (of
  // 256); 0 disables the limit. Unrelated ORB descriptors lie ~128 bits
  // apart and true matches mostly under 50, so the limit removes the chance
  // matches whose number would otherwise grow with a keyframe's feature
  // count. Range [0, 256]. Default 64.
  int max_hamming = 64;
  // SURF: a match also needs an L2 distance of at most this (descriptors are
  // unit vectors, unrelated ones ~0.5-0.7 apart); 0 disables the limit.
  // Range [0, 2]. Default 0.25.
  double max_l2 = 0.25;
  // SURF: never match descriptors whose Laplacian signs differ. Default true.
  bool use_laplacian_sign = true;
  // Each keyframe descriptor keeps at most one match, its closest query
  // descriptor (ties: the lower query index). Default true.
  bool one_to_one = true;
  // The sparse-keyframe guard (match/ratio_matcher.h): a match must also
  // be mutual and pass the ratio test against the query's descriptors.
  // Default true.
  bool cross_check = true;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<MatchOptions>& Table();
  std::string Check() const;
};

enum class GeometricModel { kFundamental, kHomography };

// "fundamental" / "homography".
const char* GeometricModelName(GeometricModel model);

// Parses those names; throws InvalidArgument.
GeometricModel ParseGeometricModel(const std::string& name);

struct VerifyOptions {
  // Verify the best candidates of the match stage and rank them by inliers.
  // Default true.
  bool enabled = true;
  // Fundamental matrix (any static scene, the robot moving) or homography
  // (planar scenes, pure rotation). Default fundamental.
  GeometricModel model = GeometricModel::kFundamental;
  // How many of the match stage's best keyframes are verified; the ranked list
  // of a verified query holds only these. Range [1, 1000]. Default 10.
  int num_candidates = 10;
  // Largest distance of an inlier from its epipolar line / its projection,
  // pixels of the query image. Range (0, 100]. Default 3.
  double max_error_px = 3.0;
  // RANSAC confidence. Range [0.5, 1). Default 0.999.
  double confidence = 0.999;
  // RANSAC iterations at most. Range [1, 100000]. Default 2000.
  int max_iterations = 2000;
  // Seed of RANSAC's sampling: the same seed, the same inliers, on any
  // thread. Range [0, 2^31). Default 0.
  int seed = 0;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<VerifyOptions>& Table();
  std::string Check() const;
};

}  // namespace placedb
