#include "placedb/builder/tracks.h"

#include <algorithm>
#include <numeric>
#include <utility>

#include "placedb/match/ratio_matcher.h"

namespace placedb {

namespace {

// The `count` nearest of n positions to each, by a scan outward from it
// in the order of x: the scan stops on a side once x alone is farther than
// the count-th nearest found.
std::vector<std::vector<size_t>> NearestByPosition(const std::vector<Eigen::Vector3d>& at,
                                                   size_t count) {
  const size_t n = at.size();
  std::vector<size_t> by_x(n);
  std::iota(by_x.begin(), by_x.end(), size_t{0});
  std::stable_sort(by_x.begin(), by_x.end(),
                   [&](size_t a, size_t b) { return at[a].x() < at[b].x(); });
  std::vector<std::vector<size_t>> out(n);
  std::vector<std::pair<double, size_t>> best;  // (squared distance, index), a max-heap
  for (size_t r = 0; r < n; ++r) {
    const size_t i = by_x[r];
    best.clear();
    const auto consider = [&](size_t j) {
      const std::pair<double, size_t> c((at[j] - at[i]).squaredNorm(), j);
      if (best.size() < count) {
        best.push_back(c);
        std::push_heap(best.begin(), best.end());
      } else if (c < best.front()) {
        std::pop_heap(best.begin(), best.end());
        best.back() = c;
        std::push_heap(best.begin(), best.end());
      }
    };
    const auto far = [&](size_t j) {
      const double dx = at[j].x() - at[i].x();
      return best.size() == count && dx * dx > best.front().first;
    };
    for (size_t l = r; l-- > 0 && !far(by_x[l]);) consider(by_x[l]);
    for (size_t h = r + 1; h < n && !far(by_x[h]); ++h) consider(by_x[h]);
    std::sort(best.begin(), best.end());
    for (const auto& b : best) out[i].push_back(b.second);
  }
  return out;
}

bool AllPosed(const std::vector<std::optional<Pose>>& poses) {
  return std::all_of(poses.begin(), poses.end(),
                     [](const std::optional<Pose>& p) { return p.has_value(); });
}

}  // namespace

std::vector<std::vector<size_t>> TrackNeighbours(const std::vector<std::optional<Pose>>& poses,
                                                 size_t count) {
  const size_t n = poses.size();
  count = std::min(count, n == 0 ? 0 : n - 1);
  if (AllPosed(poses) && count > 0) {
    std::vector<Eigen::Vector3d> at(n);
    for (size_t i = 0; i < n; ++i) at[i] = poses[i]->translation;
    return NearestByPosition(at, count);
  }
  std::vector<std::vector<size_t>> out(n);
  for (size_t i = 0; i < n; ++i) {
    for (size_t d = 1; out[i].size() < count; ++d) {
      if (i >= d) out[i].push_back(i - d);
      if (i + d < n && out[i].size() < count) out[i].push_back(i + d);
    }
  }
  return out;
}

std::vector<size_t> TrackNeighboursOfNew(const std::vector<std::optional<Pose>>& poses,
                                         const std::optional<Pose>& pose, size_t count) {
  const size_t n = poses.size();
  count = std::min(count, n);
  std::vector<size_t> out;
  if (!pose || !AllPosed(poses)) {
    for (size_t i = n; i-- > n - count;) out.push_back(i);
    return out;
  }
  std::vector<std::pair<double, size_t>> by_distance(n);
  for (size_t i = 0; i < n; ++i) {
    by_distance[i] = {(poses[i]->translation - pose->translation).squaredNorm(), i};
  }
  std::partial_sort(by_distance.begin(), by_distance.begin() + static_cast<std::ptrdiff_t>(count),
                    by_distance.end());
  for (size_t i = 0; i < count; ++i) out.push_back(by_distance[i].second);
  return out;
}

std::vector<int> TrackCounts(const FeatureSet& features,
                             const std::vector<const FeatureSet*>& neighbours) {
  std::vector<int> counts(features.keypoints.size(), 0);
  std::vector<int8_t> laplacian;
  const DescriptorBlock self = MakeDescriptorBlock(features, &laplacian);
  const MatchOptions options;
  std::vector<cv::DMatch> matches;
  for (const FeatureSet* other : neighbours) {
    if (other->keypoints.empty() || features.keypoints.empty()) continue;
    std::vector<int8_t> other_laplacian;
    const DescriptorBlock block = MakeDescriptorBlock(*other, &other_laplacian);
    matches.clear();
    MatchDescriptors(self, block, options, &matches);
    for (const cv::DMatch& m : matches) ++counts[static_cast<size_t>(m.queryIdx)];
  }
  return counts;
}

}  // namespace placedb
