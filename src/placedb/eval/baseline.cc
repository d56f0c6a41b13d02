#include "placedb/eval/baseline.h"

#include <algorithm>
#include <map>
#include <opencv2/features2d.hpp>

#include "placedb/util/check.h"

namespace placedb {

std::vector<ScoredKeyframe> BfMatcherQuery(const Database& db, const FeatureSet& query,
                                           const QueryOptions& options) {
  if (query.type != db.feature_type()) {
    PLACEDB_THROW_INVALID("cannot match ", FeatureTypeName(query.type), " query features against ",
                          "a database of ", FeatureTypeName(db.feature_type()), " features");
  }
  const bool orb = db.feature_type() == FeatureType::kOrb;
  cv::BFMatcher matcher(orb ? cv::NORM_HAMMING : cv::NORM_L2);
  const MatchOptions& mo = options.match;
  // The same distance limit as ours, so both rank the same matches.
  const double limit =
      orb ? (mo.max_hamming > 0 ? mo.max_hamming : 1e30) : (mo.max_l2 > 0 ? mo.max_l2 : 1e30);
  auto passes = [&](const std::vector<cv::DMatch>& m) {
    if (m.empty() || m[0].distance > limit) return false;
    return m.size() == 1 || m[0].distance < mo.ratio * m[1].distance;
  };
  std::vector<ScoredKeyframe> scored;
  std::vector<std::vector<cv::DMatch>> knn, back;
  for (size_t i = 0; i < db.size(); ++i) {
    const DescriptorBlock block = db.Descriptors(i);
    if (block.rows == 0 || query.descriptors.empty()) continue;
    // A header over the stored descriptors: no copy.
    const cv::Mat train(block.rows, orb ? block.row_bytes : block.row_bytes / 4,
                        orb ? CV_8U : CV_32F, const_cast<uint8_t*>(block.data));
    knn.clear();
    matcher.knnMatch(query.descriptors, train, knn, 2);
    // train index -> its closest passing query match.
    std::map<int, cv::DMatch> by_train;
    std::vector<cv::DMatch> good;
    for (const auto& m : knn) {
      if (!passes(m)) continue;
      if (!mo.one_to_one && !mo.cross_check) {
        good.push_back(m[0]);
        continue;
      }
      auto [it, inserted] = by_train.emplace(m[0].trainIdx, m[0]);
      if (!inserted &&
          (m[0].distance < it->second.distance ||
           (m[0].distance == it->second.distance && m[0].queryIdx < it->second.queryIdx)))
        it->second = m[0];
    }
    if (mo.cross_check && !by_train.empty()) {
      // One batched knnMatch back from the matched keyframe rows to the query.
      cv::Mat rows(static_cast<int>(by_train.size()), train.cols, train.type());
      int r = 0;
      for (const auto& entry : by_train) train.row(entry.first).copyTo(rows.row(r++));
      back.clear();
      matcher.knnMatch(rows, query.descriptors, back, 2);
      r = 0;
      for (const auto& [t, m] : by_train) {
        const std::vector<cv::DMatch>& b = back[r++];
        if (passes(b) && b[0].trainIdx == m.queryIdx) good.push_back(m);
      }
    } else {
      for (const auto& entry : by_train) good.push_back(entry.second);
    }
    const int count = static_cast<int>(good.size());
    if (count >= options.min_matches)
      scored.push_back({db.keyframe(i).id, static_cast<double>(count)});
  }
  return TopK(std::move(scored), options.top_k);
}

}  // namespace placedb
