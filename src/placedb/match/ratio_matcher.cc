#include "placedb/match/ratio_matcher.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "placedb/match/hamming.h"
#include "placedb/match/l2_distance.h"
#include "placedb/util/check.h"
#include "placedb/util/options.h"

namespace placedb {

std::string MatchOptions::Check() const {
  return FirstReason({CheckRange("ratio", ratio, 0.0, 1.0, /*lo_open=*/true),
                      CheckRange("max_hamming", max_hamming, 0, 256),
                      CheckRange("max_l2", max_l2, 0.0, 2.0)});
}

DescriptorBlock MakeDescriptorBlock(const FeatureSet& set, std::vector<int8_t>* laplacian) {
  DescriptorBlock block;
  block.type = set.type;
  block.rows = set.descriptors.rows;
  block.row_bytes = static_cast<int>(set.descriptors.cols * set.descriptors.elemSize());
  PLACEDB_CHECK(set.descriptors.empty() || set.descriptors.isContinuous(),
                "descriptors must be stored contiguously");
  PLACEDB_CHECK(set.descriptors.rows == static_cast<int>(set.keypoints.size()),
                "one descriptor per keypoint expected (", set.keypoints.size(), " keypoints, ",
                set.descriptors.rows, " descriptor rows)");
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

GroupedFeatures GroupByLaplacian(const FeatureSet& set) {
  GroupedFeatures g;
  if (set.type != FeatureType::kSurf || set.empty()) {
    g.set = set;
    g.block = MakeDescriptorBlock(g.set, nullptr);
    if (set.type == FeatureType::kSurf) g.block.positive_rows = 0;
    return g;
  }
  PLACEDB_CHECK(set.descriptors.rows == static_cast<int>(set.keypoints.size()),
                "one descriptor per keypoint expected");
  std::vector<int> order(set.keypoints.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  const auto mid = std::stable_partition(order.begin(), order.end(),
                                         [&](int r) { return set.keypoints[r].class_id >= 0; });
  g.set.type = set.type;
  g.set.keypoints.reserve(order.size());
  g.set.descriptors.create(set.descriptors.rows, set.descriptors.cols, set.descriptors.type());
  for (size_t i = 0; i < order.size(); ++i) {
    g.set.keypoints.push_back(set.keypoints[order[i]]);
    set.descriptors.row(order[i]).copyTo(g.set.descriptors.row(static_cast<int>(i)));
  }
  g.block = MakeDescriptorBlock(g.set, nullptr);
  g.block.positive_rows = static_cast<int>(mid - order.begin());
  return g;
}

namespace {

// The distance of one descriptor family: ORB's Hamming counts or SURF's
// squared L2, with its limit and ratio test in the same (squared) units.
struct OrbMetric {
  using Distance = uint32_t;
  uint32_t limit;
  double ratio;
  OrbMetric(const MatchOptions& o)
      : limit(o.max_hamming > 0 ? static_cast<uint32_t>(o.max_hamming) : UINT32_MAX),
        ratio(o.ratio) {}
  TwoNearestOf<uint32_t> Nearest(const DescriptorBlock& from, int row,
                                 const DescriptorBlock& in) const {
    return TwoNearestHamming(from.Row(row), in.data, in.rows, in.row_bytes);
  }
  // second == UINT32_MAX (one candidate) always passes.
  bool Passes(const TwoNearestOf<uint32_t>& nn) const {
    return nn.best_index >= 0 && nn.best <= limit &&
           static_cast<double>(nn.best) < ratio * static_cast<double>(nn.second);
  }
  float Reported(uint32_t d) const { return static_cast<float>(d); }
};

// The sign of row `i`'s Laplacian, 0 when the block does not know it.
int8_t RowSign(const DescriptorBlock& b, int i) {
  if (b.laplacian != nullptr) return b.laplacian[i];
  if (b.positive_rows >= 0) return i < b.positive_rows ? 1 : -1;
  return 0;
}

struct SurfMetric {
  using Distance = float;
  float limit;
  double ratio2;  // squared distances are compared
  bool use_signs;
  explicit SurfMetric(const MatchOptions& o)
      : limit(o.max_l2 > 0 ? static_cast<float>(o.max_l2 * o.max_l2)
                           : std::numeric_limits<float>::infinity()),
        ratio2(o.ratio * o.ratio),
        use_signs(o.use_laplacian_sign) {}
  // The two nearest rows of `in` to row `row` of `from` among the rows of
  // the same Laplacian sign: a range of grouped rows, or a per-row filter.
  TwoNearestOf<float> Nearest(const DescriptorBlock& from, int row,
                              const DescriptorBlock& in) const {
    const int dims = in.row_bytes / static_cast<int>(sizeof(float));
    const auto* q = reinterpret_cast<const float*>(from.Row(row));
    const auto* d = reinterpret_cast<const float*>(in.data);
    const int8_t sign = use_signs ? RowSign(from, row) : int8_t{0};
    if (sign != 0 && in.positive_rows >= 0) {
      const int begin = sign > 0 ? 0 : in.positive_rows;
      const int end = sign > 0 ? in.positive_rows : in.rows;
      TwoNearestOf<float> nn =
          TwoNearestL2(q, d + static_cast<size_t>(begin) * dims, end - begin, dims, nullptr, 0);
      if (nn.best_index >= 0) nn.best_index += begin;
      return nn;
    }
    const bool filter = sign != 0 && in.laplacian != nullptr;
    return TwoNearestL2(q, d, in.rows, dims, filter ? in.laplacian : nullptr,
                        filter ? sign : int8_t{0});
  }
  bool Passes(const TwoNearestOf<float>& nn) const {
    return nn.best_index >= 0 && nn.best <= limit &&
           (std::isinf(nn.second) || nn.best < ratio2 * nn.second);
  }
  float Reported(float d) const { return std::sqrt(d); }
};

template <typename Metric>
int Match(const DescriptorBlock& query, const DescriptorBlock& db, const Metric& metric,
          const MatchOptions& options, std::vector<cv::DMatch>* out) {
  using Distance = typename Metric::Distance;
  struct Tentative {
    int q, t;
    Distance d;
  };
  std::vector<Tentative> tentative;
  for (int i = 0; i < query.rows; ++i) {
    const auto nn = metric.Nearest(query, i, db);
    if (metric.Passes(nn)) tentative.push_back({i, nn.best_index, nn.best});
  }
  if (options.one_to_one || options.cross_check) {
    // The closest query descriptor per keyframe descriptor (ties: lower q).
    std::sort(tentative.begin(), tentative.end(), [](const Tentative& a, const Tentative& b) {
      if (a.t != b.t) return a.t < b.t;
      if (a.d != b.d) return a.d < b.d;
      return a.q < b.q;
    });
    tentative.erase(std::unique(tentative.begin(), tentative.end(),
                                [](const Tentative& a, const Tentative& b) { return a.t == b.t; }),
                    tentative.end());
  }
  if (options.cross_check) {
    // q must be t's nearest among the query's descriptors and pass the ratio
    // test there. (A mutual pair is also one-to-one.)
    tentative.erase(std::remove_if(tentative.begin(), tentative.end(),
                                   [&](const Tentative& m) {
                                     const auto back = metric.Nearest(db, m.t, query);
                                     return back.best_index != m.q || !metric.Passes(back);
                                   }),
                    tentative.end());
  }
  if (out != nullptr) {
    std::sort(tentative.begin(), tentative.end(),
              [](const Tentative& a, const Tentative& b) { return a.q < b.q; });
    for (const Tentative& m : tentative) out->emplace_back(m.q, m.t, metric.Reported(m.d));
  }
  return static_cast<int>(tentative.size());
}

}  // namespace

int MatchDescriptors(const DescriptorBlock& query, const DescriptorBlock& db,
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
    return Match(query, db, OrbMetric(options), options, matches);
  return Match(query, db, SurfMetric(options), options, matches);
}

}  // namespace placedb
