#include "placedb/match/ratio_matcher.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <type_traits>

#include "placedb/match/hamming.h"
#include "placedb/match/l2_distance.h"
#include "placedb/util/check.h"
#include "placedb/util/options.h"

namespace placedb {

DescriptorBlock MakeDescriptorBlock(const FeatureSet& set, std::vector<int8_t>* laplacian) {
  DescriptorBlock block;
  block.type = set.type;
  block.rows = set.descriptors.rows;
  block.row_bytes = static_cast<int>(set.descriptors.cols * set.descriptors.elemSize());
  // Feature sets come from callers (features given from outside).
  if (!set.descriptors.empty() && !set.descriptors.isContinuous()) {
    PLACEDB_THROW_INVALID("the descriptors must be one contiguous matrix");
  }
  if (set.descriptors.rows != static_cast<int>(set.keypoints.size())) {
    PLACEDB_THROW_INVALID("one descriptor per keypoint expected (", set.keypoints.size(),
                          " keypoints, ", set.descriptors.rows, " descriptor rows)");
  }
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
  if (set.descriptors.rows != static_cast<int>(set.keypoints.size())) {
    PLACEDB_THROW_INVALID("one descriptor per keypoint expected (", set.keypoints.size(),
                          " keypoints, ", set.descriptors.rows, " descriptor rows)");
  }
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
  // Every row of `from` against `in` (forward), and with `backward` wanted
  // and a one-pass kernel, every row of `in` against `from`; else backward
  // is left empty.
  void NearestAll(const DescriptorBlock& from, const DescriptorBlock& in, bool want_backward,
                  std::vector<TwoNearestOf<uint32_t>>* forward,
                  std::vector<TwoNearestOf<uint32_t>>* backward) const {
    forward->resize(static_cast<size_t>(from.rows));
    if (want_backward && HammingBothIsOnePass(from.rows, in.rows, in.row_bytes)) {
      backward->resize(static_cast<size_t>(in.rows));
      TwoNearestHammingBoth(from.data, from.rows, in.data, in.rows, in.row_bytes, forward->data(),
                            backward->data());
      return;
    }
    backward->clear();
    TwoNearestHammingBatch(from.data, from.rows, in.data, in.rows, in.row_bytes, forward->data());
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
  void NearestAll(const DescriptorBlock& from, const DescriptorBlock& in, bool /*want_backward*/,
                  std::vector<TwoNearestOf<float>>* forward,
                  std::vector<TwoNearestOf<float>>* backward) const {
    forward->resize(static_cast<size_t>(from.rows));
    for (int i = 0; i < from.rows; ++i) (*forward)[i] = Nearest(from, i, in);
    backward->clear();
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
  thread_local std::vector<Tentative> tentative;
  tentative.clear();
  // Forward: each query row's two nearest keyframe rows; with the cross
  // check, the metric may give each keyframe row's two nearest query rows
  // from the same pass (else they are computed for the survivors below).
  thread_local std::vector<TwoNearestOf<Distance>> forward, backward;
  metric.NearestAll(query, db, options.cross_check, &forward, &backward);
  for (int i = 0; i < query.rows; ++i) {
    const auto& nn = forward[i];
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
                                     const auto back = backward.empty()
                                                           ? metric.Nearest(db, m.t, query)
                                                           : backward[m.t];
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

int GuidedLabels::Find(uint32_t label) const {
  if (!dense.empty()) {
    const uint32_t x = label - lowest;  // wraps for labels below: out of range
    return x < dense.size() ? dense[x] : -1;
  }
  const auto it = std::lower_bound(distinct.begin(), distinct.end(), label);
  return it != distinct.end() && *it == label ? static_cast<int>(it - distinct.begin()) : -1;
}

namespace {

// The keyframe rows gathered by label (a counting sort, stable: row order
// within a label), so that each query row is compared with its label's rows
// by one call of the metric's SIMD two-nearest kernel, as MatchDescriptors
// compares it with all of them. Per thread, reused across calls.
struct GuidedScratch {
  std::vector<int32_t> label_of_row;  // keyframe row -> index in the query's distinct labels
  std::vector<uint32_t> start;        // label l's rows: gathered [start[l], start[l + 1])
  std::vector<uint32_t> fill;
  std::vector<uint8_t> rows;  // the gathered descriptors
  std::vector<int8_t> signs;  // their Laplacian signs (SURF, when the keyframe's are known)
};

// For each query row: its two nearest among the keyframe rows of its own
// label (ties: the lower keyframe row), judged by the metric's rules.
// `sorted_rows`: ORB, the query's rows in `order` (label by label), back to
// back.
template <typename Metric>
int CountGuided(const DescriptorBlock& query, const GuidedLabels& labels,
                const std::vector<uint32_t>& begin, const std::vector<uint32_t>& order,
                const std::vector<uint8_t>& sorted_rows, const DescriptorBlock& db,
                const uint32_t* db_labels, const Metric& metric) {
  thread_local GuidedScratch s;
  const size_t num_labels = labels.distinct.size();
  s.label_of_row.resize(static_cast<size_t>(db.rows));
  s.start.assign(num_labels + 1, 0);
  for (int t = 0; t < db.rows; ++t) {
    const int l = labels.Find(db_labels[t]);
    s.label_of_row[t] = l;
    if (l >= 0) ++s.start[l + 1];
  }
  for (size_t l = 0; l < num_labels; ++l) s.start[l + 1] += s.start[l];
  const uint32_t gathered = s.start[num_labels];
  if (gathered == 0) return 0;
  const size_t row_bytes = static_cast<size_t>(db.row_bytes);
  s.rows.resize(static_cast<size_t>(gathered) * row_bytes);
  const bool with_signs = db.laplacian != nullptr || db.positive_rows >= 0;
  s.signs.resize(with_signs ? gathered : 0);
  s.fill.assign(s.start.begin(), s.start.end() - 1);
  for (int t = 0; t < db.rows; ++t) {
    const int l = s.label_of_row[t];
    if (l < 0) continue;
    const uint32_t at = s.fill[l]++;
    if (row_bytes == 32) {
      std::memcpy(s.rows.data() + at * 32, db.Row(t), 32);  // inlined
    } else {
      std::memcpy(s.rows.data() + at * row_bytes, db.Row(t), row_bytes);
    }
    if (with_signs) s.signs[at] = RowSign(db, t);
  }
  int count = 0;
  for (size_t l = 0; l < num_labels; ++l) {
    if (s.start[l + 1] == s.start[l]) continue;
    DescriptorBlock group;
    group.type = db.type;
    group.row_bytes = db.row_bytes;
    group.rows = static_cast<int>(s.start[l + 1] - s.start[l]);
    group.data = s.rows.data() + s.start[l] * row_bytes;
    if (with_signs) group.laplacian = s.signs.data() + s.start[l];
    if constexpr (std::is_same_v<Metric, OrbMetric>) {
      // The label's query rows against its keyframe rows, in one call.
      thread_local std::vector<TwoNearest> nearest;
      const uint32_t n = begin[l + 1] - begin[l];
      nearest.resize(n);
      TwoNearestHammingBatch(sorted_rows.data() + static_cast<size_t>(begin[l]) * row_bytes,
                             static_cast<int>(n), group.data, group.rows, group.row_bytes,
                             nearest.data());
      for (const TwoNearest& nn : nearest) count += metric.Passes(nn);
    } else {
      for (uint32_t k = begin[l]; k < begin[l + 1]; ++k)
        count += metric.Passes(metric.Nearest(query, static_cast<int>(order[k]), group));
    }
  }
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
  if (query.type == FeatureType::kOrb && query.rows > 0) {
    const size_t row_bytes = static_cast<size_t>(query.row_bytes);
    sorted_rows_.resize(rows * row_bytes);
    for (size_t i = 0; i < rows; ++i)
      std::memcpy(sorted_rows_.data() + i * row_bytes, query.Row(static_cast<int>(order_[i])),
                  row_bytes);
  }
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
    return CountGuided(query_, labels_, begin_, order_, sorted_rows_, db, labels, metric);
  }
  const SurfMetric metric(options_);
  return CountGuided(query_, labels_, begin_, order_, sorted_rows_, db, labels, metric);
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
