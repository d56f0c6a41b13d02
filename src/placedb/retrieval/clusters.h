// Spatial-locality clusters (the paper's future work): keyframes grouped by
// where they were taken, with a neighbour graph, so that a query that knows
// roughly where the robot is (the last answer, or a pose) searches a few
// clusters instead of the whole database.
//
// With poses, keyframes are grouped by position: in keyframe order, each
// joins the cluster whose seed (first keyframe) is nearest within `radius_m`,
// else it seeds a new cluster (a grid over the seeds makes this linear).
// Without poses they are grouped by time: runs of `time_keyframes`
// consecutive keyframes. Two clusters are neighbours when consecutive
// keyframes (the trajectory) cross from one to the other, or when their
// seeds are within 2 * radius_m: the transitions a moving robot makes.
// Keyframes added later (online mapping) join the same way (Add).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "placedb/storage/database.h"
#include "placedb/util/pose.h"
#include "placedb/retrieval/options.h"

namespace placedb {

class ClusterSet {
 public:
  ClusterSet() = default;
  // Clusters of `db`'s keyframes. Pose-based when every keyframe has a pose,
  // else time-based (keyframe order).
  static ClusterSet Make(const Database& db, const ClusterOptions& options);
  // Places the next keyframe (index size_of_keyframes()) in a cluster, as
  // Make does. In a pose-based set a keyframe without a pose joins the
  // previous keyframe's cluster.
  void Add(const Keyframe& keyframe);

  bool by_pose() const { return by_pose_; }
  size_t size() const { return members_.size(); }
  size_t num_keyframes() const { return cluster_of_.size(); }
  // The cluster of keyframe index `index`.
  int ClusterOf(uint32_t index) const { return cluster_of_[index]; }
  // Keyframe indices of cluster `c`, ascending.
  const std::vector<uint32_t>& Members(int c) const { return members_[c]; }
  // Neighbouring clusters of `c`, ascending (not `c` itself).
  const std::vector<int>& Neighbours(int c) const { return neighbours_[c]; }
  // The cluster whose seed is nearest to `position` (pose-based only, else -1).
  int Nearest(const Eigen::Vector3d& position) const;
  // Clusters within `hops` of the neighbour graph from `c` (c included),
  // ascending.
  std::vector<int> Around(int c, int hops) const;
  // Keyframe indices of those clusters, ascending.
  std::vector<uint32_t> KeyframesAround(int c, int hops) const;

 private:
  // Seeds within `radius` of `p` (a grid of cells radius_m wide).
  std::vector<int> SeedsWithin(const Eigen::Vector3d& p, double radius) const;
  void Link(int a, int b);

  ClusterOptions options_;
  bool by_pose_ = false;
  std::vector<int> cluster_of_;
  std::vector<std::vector<uint32_t>> members_;
  std::vector<std::vector<int>> neighbours_;  // kept sorted
  std::vector<Eigen::Vector3d> seeds_;
  std::unordered_map<uint64_t, std::vector<int>> grid_;  // cell -> seeds
};

}  // namespace placedb
