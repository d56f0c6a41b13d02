#include "placedb/match/ratio_matcher.h"

#include <cmath>
#include <limits>

#include "placedb/match/hamming.h"
#include "placedb/match/l2_distance.h"
#include "placedb/util/check.h"

namespace placedb {

std::string MatchOptions::Check() const {
  if (!(ratio > 0.0 && ratio <= 1.0)) return "ratio must be in (0, 1]";
  if (max_hamming < 0) return "max_hamming must be >= 0";
  if (max_l2 < 0) return "max_l2 must be >= 0";
  return "";
}

DescriptorBlock MakeDescriptorBlock(const FeatureSet& set, std::vector<int8_t>* laplacian) {
  DescriptorBlock block;
  block.type = set.type;
  block.rows = set.descriptors.rows;
  block.row_bytes = static_cast<int>(set.descriptors.cols * set.descriptors.elemSize());
  PLACEDB_CHECK(set.descriptors.empty() || set.descriptors.isContinuous(),
                "descriptors must be stored contiguously");
  block.data = set.descriptors.empty() ? nullptr : set.descriptors.ptr<uint8_t>();
  if (set.type == FeatureType::kSurf && laplacian != nullptr) {
    laplacian->resize(set.keypoints.size());
    for (size_t i = 0; i < set.keypoints.size(); ++i) {
      (*laplacian)[i] = set.keypoints[i].class_id < 0 ? -1 : 1;
    }
    block.laplacian = laplacian->data();
  }
  return block;
}

namespace {

int CountOrb(const DescriptorBlock& query, const DescriptorBlock& db, double ratio, int max_hamming,
             std::vector<cv::DMatch>* matches) {
  const uint32_t limit = max_hamming > 0 ? static_cast<uint32_t>(max_hamming) : UINT32_MAX;
  int good = 0;
  for (int i = 0; i < query.rows; ++i) {
    const TwoNearest nn = TwoNearestHamming(query.data + static_cast<size_t>(i) * query.row_bytes,
                                            db.data, db.rows, db.row_bytes);
    if (nn.best_index < 0 || nn.best > limit) continue;
    // second == UINT32_MAX (one candidate) always passes.
    if (static_cast<double>(nn.best) < ratio * static_cast<double>(nn.second)) {
      ++good;
      if (matches) matches->emplace_back(i, nn.best_index, static_cast<float>(nn.best));
    }
  }
  return good;
}

int CountSurf(const DescriptorBlock& query, const DescriptorBlock& db, double ratio, double max_l2,
              bool use_sign, std::vector<cv::DMatch>* matches) {
  const float limit =
      max_l2 > 0 ? static_cast<float>(max_l2 * max_l2) : std::numeric_limits<float>::infinity();
  const int dims = query.row_bytes / static_cast<int>(sizeof(float));
  const double ratio2 = ratio * ratio;  // compare squared distances
  const bool signs = use_sign && query.laplacian != nullptr && db.laplacian != nullptr;
  const auto* q_all = reinterpret_cast<const float*>(query.data);
  const auto* d_all = reinterpret_cast<const float*>(db.data);
  int good = 0;
  for (int i = 0; i < query.rows; ++i) {
    const float* q = q_all + static_cast<size_t>(i) * dims;
    const TwoNearestL2Result nn =
        TwoNearestL2(q, d_all, db.rows, dims, signs ? db.laplacian : nullptr,
                     signs ? query.laplacian[i] : int8_t{0});
    if (nn.best_index < 0 || nn.best > limit) continue;
    if (std::isinf(nn.second) || nn.best < ratio2 * nn.second) {
      ++good;
      if (matches) matches->emplace_back(i, nn.best_index, std::sqrt(nn.best));
    }
  }
  return good;
}

}  // namespace

int CountRatioMatches(const DescriptorBlock& query, const DescriptorBlock& db,
                      const MatchOptions& options, std::vector<cv::DMatch>* matches) {
  if (query.type != db.type) {
    PLACEDB_THROW_INVALID("cannot match ", FeatureTypeName(query.type), " descriptors against ",
                          FeatureTypeName(db.type), " descriptors");
  }
  if (query.rows == 0 || db.rows == 0) return 0;
  if (query.row_bytes != db.row_bytes) {
    PLACEDB_THROW_INVALID("descriptor widths differ: ", query.row_bytes, " vs ", db.row_bytes,
                          " bytes");
  }
  if (query.type == FeatureType::kOrb)
    return CountOrb(query, db, options.ratio, options.max_hamming, matches);
  return CountSurf(query, db, options.ratio, options.max_l2, options.use_laplacian_sign, matches);
}

}  // namespace placedb
