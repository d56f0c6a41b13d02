#include "placedb/feature/spread.h"

#include <algorithm>
#include <numeric>
#include <vector>

#include "placedb/util/check.h"

namespace placedb {

namespace {

int Cell(float v, int side, int cells) {
  if (side <= 0 || !(v > 0.0f)) return 0;  // also NaN
  const int c = static_cast<int>(static_cast<double>(v) * cells / side);
  return std::min(c, cells - 1);
}

}  // namespace

void KeepSpread(FeatureSet* features, size_t max_features, cv::Size image_size,
                const std::vector<int>& priority) {
  FeatureSet& f = *features;
  const size_t n = f.keypoints.size();
  if (max_features == 0 || n <= max_features) return;
  PLACEDB_CHECK(f.descriptors.rows == static_cast<int>(n), "KeepSpread: ", n, " keypoints but ",
                f.descriptors.rows, " descriptor rows");
  PLACEDB_CHECK(priority.empty() || priority.size() == n, "KeepSpread: ", n, " keypoints but ",
                priority.size(), " priorities");
  // Strongest first (ties: the earlier), then each feature's rank in its cell.
  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return f.keypoints[a].response > f.keypoints[b].response;
  });
  // Cells count their features per priority.
  const auto level = [&](size_t i) { return priority.empty() ? 0 : priority[i]; };
  std::vector<int> levels(n);
  for (size_t i = 0; i < n; ++i) levels[i] = level(i);
  std::sort(levels.begin(), levels.end());
  levels.erase(std::unique(levels.begin(), levels.end()), levels.end());
  constexpr size_t kCells = kSpreadColumns * kSpreadRows;
  std::vector<size_t> rank(n);
  std::vector<size_t> taken(kCells * levels.size(), 0);
  for (const size_t i : order) {
    const cv::Point2f& p = f.keypoints[i].pt;
    const size_t cell = Cell(p.y, image_size.height, kSpreadRows) * kSpreadColumns +
                        Cell(p.x, image_size.width, kSpreadColumns);
    const size_t l = std::lower_bound(levels.begin(), levels.end(), level(i)) - levels.begin();
    rank[i] = taken[l * kCells + cell]++;
  }
  // The higher priority first, then round by round; stable, so within a
  // round the response order holds.
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    if (level(a) != level(b)) return level(a) > level(b);
    return rank[a] < rank[b];
  });
  order.resize(max_features);
  std::sort(order.begin(), order.end());
  std::vector<cv::KeyPoint> keypoints;
  keypoints.reserve(max_features);
  cv::Mat descriptors(static_cast<int>(max_features), f.descriptors.cols, f.descriptors.type());
  for (size_t j = 0; j < order.size(); ++j) {
    keypoints.push_back(f.keypoints[order[j]]);
    f.descriptors.row(static_cast<int>(order[j])).copyTo(descriptors.row(static_cast<int>(j)));
  }
  f.keypoints = std::move(keypoints);
  f.descriptors = descriptors;
}

}  // namespace placedb
