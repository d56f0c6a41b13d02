#include "placedb/match/ratio_matcher.h"

#include <algorithm>
#include <cmath>
#include <cstring>
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

namespace {

uint32_t PairDistance(const OrbMetric&, const DescriptorBlock& a, int i, const DescriptorBlock& b,
                      int j) {
  return Hamming(a.Row(i), b.Row(j), a.row_bytes);
}
float PairDistance(const SurfMetric&, const DescriptorBlock& a, int i, const DescriptorBlock& b,
                   int j) {
  return L2Squared(reinterpret_cast<const float*>(a.Row(i)),
                   reinterpret_cast<const float*>(b.Row(j)),
                   a.row_bytes / static_cast<int>(sizeof(float)));
}
bool SignsAgree(const OrbMetric&, const DescriptorBlock&, int, const DescriptorBlock&, int) {
  return true;
}
bool SignsAgree(const SurfMetric& m, const DescriptorBlock& a, int i, const DescriptorBlock& b,
                int j) {
  if (!m.use_signs) return true;
  const int8_t sa = RowSign(a, i), sb = RowSign(b, j);
  return sa == 0 || sb == 0 || sa == sb;
}

}  // namespace

int GuidedLabels::Find(uint32_t label) const {
  if (!dense.empty()) {
    const uint32_t x = label - lowest;  // wraps for labels below: out of range
    return x < dense.size() ? dense[x] : -1;
  }
  const auto it = std::lower_bound(distinct.begin(), distinct.end(), label);
  return it != distinct.end() && *it == label ? static_cast<int>(it - distinct.begin()) : -1;
}

namespace {

// Each keyframe row t updates the two nearest of the query rows of its
// label (distance(q, t)); then the query rows that found a partner are
// judged.
template <typename Metric, typename DistanceFn>
int CountGuided(const DescriptorBlock& query, const GuidedLabels& labels,
                const std::vector<uint32_t>& begin, const std::vector<uint32_t>& order,
                const DescriptorBlock& db, const uint32_t* db_labels, const Metric& metric,
                const DistanceFn& distance) {
  using Distance = typename Metric::Distance;
  thread_local std::vector<TwoNearestOf<Distance>> nearest;
  nearest.assign(static_cast<size_t>(query.rows), TwoNearestOf<Distance>());
  for (int t = 0; t < db.rows; ++t) {
    const int l = labels.Find(db_labels[t]);
    if (l < 0) continue;
    for (uint32_t k = begin[l]; k < begin[l + 1]; ++k) {
      const int q = static_cast<int>(order[k]);
      if (SignsAgree(metric, query, q, db, t)) nearest[q].Update(distance(q, t), t);
    }
  }
  int count = 0;
  for (const TwoNearestOf<Distance>& nn : nearest) count += metric.Passes(nn);
  return count;
}

}  // namespace

GuidedMatcher::GuidedMatcher(const DescriptorBlock& query, const uint32_t* labels, size_t rows,
                             const MatchOptions& options)
    : query_(query), options_(options) {
  if (rows != static_cast<size_t>(query.rows)) {
    PLACEDB_THROW_INVALID("guided matching needs one label per query row (", rows, " for ",
                          query.rows, " rows)");
  }
  std::vector<std::pair<uint32_t, uint32_t>> by_label(rows);
  for (size_t i = 0; i < rows; ++i) by_label[i] = {labels[i], static_cast<uint32_t>(i)};
  std::sort(by_label.begin(), by_label.end());
  order_.reserve(rows);
  for (size_t i = 0; i < rows; ++i) {
    if (i == 0 || by_label[i].first != by_label[i - 1].first) {
      labels_.distinct.push_back(by_label[i].first);
      begin_.push_back(static_cast<uint32_t>(i));
    }
    order_.push_back(by_label[i].second);
  }
  begin_.push_back(static_cast<uint32_t>(rows));
  // A keyframe row finds its label's query rows by a table lookup (a
  // vocabulary level's nodes have neighbouring ids) when the labels span
  // little, else by binary search.
  if (!labels_.distinct.empty()) {
    const uint64_t span =
        static_cast<uint64_t>(labels_.distinct.back()) - labels_.distinct.front() + 1;
    if (span <= (uint64_t{1} << 20)) {
      labels_.lowest = labels_.distinct.front();
      labels_.dense.assign(span, -1);
      for (size_t l = 0; l < labels_.distinct.size(); ++l)
        labels_.dense[labels_.distinct[l] - labels_.lowest] = static_cast<int32_t>(l);
    }
  }
}

int GuidedMatcher::Count(const DescriptorBlock& db, const uint32_t* labels, size_t rows) const {
  if (query_.type != db.type) {
    PLACEDB_THROW_INVALID("cannot match ", FeatureTypeName(query_.type), " descriptors against ",
                          FeatureTypeName(db.type), " descriptors");
  }
  if (rows != static_cast<size_t>(db.rows)) {
    PLACEDB_THROW_INVALID("guided matching needs one label per keyframe row (", rows, " for ",
                          db.rows, " rows)");
  }
  if (query_.rows == 0 || db.rows == 0) return 0;
  if (query_.row_bytes != db.row_bytes) {
    PLACEDB_THROW_INVALID("descriptor widths differ: ", query_.row_bytes, " vs ", db.row_bytes,
                          " bytes");
  }
  if (query_.type == FeatureType::kOrb) {
    const OrbMetric metric(options_);
    return CountGuided(query_, labels_, begin_, order_, db, labels, metric,
                       [&](int q, int t) { return PairDistance(metric, query_, q, db, t); });
  }
  const SurfMetric metric(options_);
  return CountGuided(query_, labels_, begin_, order_, db, labels, metric,
                     [&](int q, int t) { return PairDistance(metric, query_, q, db, t); });
}

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
