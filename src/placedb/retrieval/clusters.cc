#include "placedb/retrieval/clusters.h"

#include <algorithm>
#include <cmath>

#include "placedb/util/check.h"
#include "placedb/util/options.h"

namespace placedb {

namespace {

// Grid cell of a coordinate, clamped so that far-away poses cannot overflow.
int64_t CellOf(double v, double cell) {
  return static_cast<int64_t>(std::clamp(std::floor(v / cell), -1e15, 1e15));
}

uint64_t CellKey(int64_t x, int64_t y, int64_t z) {
  uint64_t h = static_cast<uint64_t>(x) * 0x9E3779B97F4A7C15ull;
  h ^= static_cast<uint64_t>(y) * 0xC2B2AE3D27D4EB4Full + (h << 6) + (h >> 2);
  h ^= static_cast<uint64_t>(z) * 0x165667B19E3779F9ull + (h << 6) + (h >> 2);
  return h;
}

}  // namespace

ClusterSet ClusterSet::Make(const Database& db, const ClusterOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  ClusterSet set;
  set.options_ = options;
  set.by_pose_ = !db.empty();
  for (size_t i = 0; i < db.size() && set.by_pose_; ++i)
    set.by_pose_ = db.keyframe(i).pose.has_value();
  for (size_t i = 0; i < db.size(); ++i) set.Add(db.keyframe(i));
  return set;
}

std::vector<int> ClusterSet::SeedsWithin(const Eigen::Vector3d& p, double radius) const {
  const double cell = options_.radius_m;
  const int64_t reach = static_cast<int64_t>(std::ceil(radius / cell));
  const int64_t cx = CellOf(p.x(), cell), cy = CellOf(p.y(), cell), cz = CellOf(p.z(), cell);
  std::vector<int> out;
  for (int64_t dx = -reach; dx <= reach; ++dx) {
    for (int64_t dy = -reach; dy <= reach; ++dy) {
      for (int64_t dz = -reach; dz <= reach; ++dz) {
        const auto it = grid_.find(CellKey(cx + dx, cy + dy, cz + dz));
        if (it == grid_.end()) continue;
        for (const int s : it->second) {
          if ((seeds_[s] - p).squaredNorm() <= radius * radius) out.push_back(s);
        }
      }
    }
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());  // hash collisions
  return out;
}

void ClusterSet::Link(int a, int b) {
  if (a == b) return;
  for (const auto& [from, to] : {std::pair<int, int>{a, b}, std::pair<int, int>{b, a}}) {
    std::vector<int>& list = neighbours_[from];
    const auto it = std::lower_bound(list.begin(), list.end(), to);
    if (it == list.end() || *it != to) list.insert(it, to);
  }
}

void ClusterSet::Add(const Keyframe& keyframe) {
  const uint32_t index = static_cast<uint32_t>(cluster_of_.size());
  const int previous = cluster_of_.empty() ? -1 : cluster_of_.back();
  auto new_cluster = [&] {
    members_.emplace_back();
    neighbours_.emplace_back();
    return static_cast<int>(members_.size() - 1);
  };
  int c = -1;
  if (by_pose_ && keyframe.pose && keyframe.pose->translation.allFinite()) {
    const Eigen::Vector3d& p = keyframe.pose->translation;
    double best = 0.0;
    for (const int s : SeedsWithin(p, options_.radius_m)) {
      const double d = (seeds_[s] - p).squaredNorm();
      if (c < 0 || d < best) {
        c = s;
        best = d;
      }
    }
    if (c < 0) {
      c = new_cluster();
      seeds_.push_back(p);
      for (const int s : SeedsWithin(p, 2.0 * options_.radius_m)) Link(c, s);
      const double cell = options_.radius_m;
      grid_[CellKey(CellOf(p.x(), cell), CellOf(p.y(), cell), CellOf(p.z(), cell))].push_back(c);
    }
  } else if (by_pose_) {
    c = previous >= 0 ? previous : new_cluster();
    if (seeds_.size() < members_.size()) seeds_.push_back(Eigen::Vector3d::Zero());
  } else {
    const size_t slot = index / static_cast<size_t>(options_.time_keyframes);
    c = slot < members_.size() ? static_cast<int>(slot) : new_cluster();
  }
  cluster_of_.push_back(c);
  members_[c].push_back(index);
  if (previous >= 0) Link(previous, c);
}

int ClusterSet::Nearest(const Eigen::Vector3d& position) const {
  if (!by_pose_ || !position.allFinite()) return -1;
  int best = -1;
  double best_d = 0.0;
  for (size_t c = 0; c < seeds_.size(); ++c) {
    const double d = (seeds_[c] - position).squaredNorm();
    if (best < 0 || d < best_d) {
      best = static_cast<int>(c);
      best_d = d;
    }
  }
  return best;
}

std::vector<int> ClusterSet::Around(int c, int hops) const {
  if (c < 0 || static_cast<size_t>(c) >= members_.size()) {
    PLACEDB_THROW_INVALID("cluster ", c, " is out of range (there are ", members_.size(), ")");
  }
  std::vector<int> frontier{c}, all{c};
  std::vector<char> seen(members_.size(), 0);
  seen[c] = 1;
  for (int h = 0; h < hops && !frontier.empty(); ++h) {
    std::vector<int> next;
    for (const int f : frontier) {
      for (const int g : neighbours_[f]) {
        if (seen[g]) continue;
        seen[g] = 1;
        next.push_back(g);
        all.push_back(g);
      }
    }
    frontier = std::move(next);
  }
  std::sort(all.begin(), all.end());
  return all;
}

std::vector<uint32_t> ClusterSet::KeyframesAround(int c, int hops) const {
  std::vector<uint32_t> out;
  for (const int g : Around(c, hops)) out.insert(out.end(), members_[g].begin(), members_[g].end());
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace placedb
