#include "placedb/eval/baseline.h"

#include <opencv2/features2d.hpp>

#include "placedb/util/check.h"

namespace placedb {

std::vector<ScoredKeyframe> BfMatcherQuery(const Database& db, const FeatureSet& query,
                                           const QueryOptions& options) {
  PLACEDB_CHECK(query.type == db.feature_type(), "query and database feature types differ");
  const bool orb = db.feature_type() == FeatureType::kOrb;
  cv::BFMatcher matcher(orb ? cv::NORM_HAMMING : cv::NORM_L2);
  // The same distance limit as ours, so both rank the same matches.
  const double limit = orb ? (options.match.max_hamming > 0 ? options.match.max_hamming : 1e30)
                           : (options.match.max_l2 > 0 ? options.match.max_l2 : 1e30);
  std::vector<ScoredKeyframe> scored;
  std::vector<std::vector<cv::DMatch>> knn;
  for (size_t i = 0; i < db.size(); ++i) {
    const DescriptorBlock block = db.Descriptors(i);
    if (block.rows == 0 || query.descriptors.empty()) continue;
    // A header over the stored descriptors: no copy.
    const cv::Mat train(block.rows, orb ? block.row_bytes : block.row_bytes / 4,
                        orb ? CV_8U : CV_32F, const_cast<uint8_t*>(block.data));
    knn.clear();
    matcher.knnMatch(query.descriptors, train, knn, 2);
    int good = 0;
    for (const auto& m : knn) {
      if (m.empty() || m[0].distance > limit) continue;
      if (m.size() == 1 || m[0].distance < options.match.ratio * m[1].distance) {
        ++good;
      }
    }
    if (good >= options.min_matches)
      scored.push_back({db.keyframe(i).id, static_cast<double>(good)});
  }
  return TopK(std::move(scored), options.top_k);
}

}  // namespace placedb
