#include "placedb/eval/classic_baselines.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <opencv2/objdetect.hpp>

#include "placedb/feature/options.h"
#include "placedb/feature/whole_image.h"
#include "placedb/feature/whole_image_model.h"
#include "placedb/image/chromaticity.h"
#include "placedb/query/sequence.h"
#include "placedb/util/check.h"

namespace placedb {

const char* EvalBaselineName(EvalBaseline b) {
  switch (b) {
    case EvalBaseline::kHog:
      return "hog";
    case EvalBaseline::kSeqSlam:
      return "seqslam";
    case EvalBaseline::kBoth:
      return "both";
    case EvalBaseline::kNone:
      break;
  }
  return "none";
}

EvalBaseline ParseEvalBaseline(const std::string& name) {
  for (const EvalBaseline b :
       {EvalBaseline::kNone, EvalBaseline::kHog, EvalBaseline::kSeqSlam, EvalBaseline::kBoth}) {
    if (name == EvalBaselineName(b)) return b;
  }
  PLACEDB_THROW_INVALID("unknown baseline '", name, "' (none, hog, seqslam or both)");
}

namespace {

constexpr int kWidth = 64;

// The best `most` of `score` (larger first; ties: the lower index).
std::vector<size_t> Best(const std::vector<double>& score, size_t most) {
  std::vector<size_t> order(score.size());
  std::iota(order.begin(), order.end(), size_t{0});
  const size_t k = std::min(most, order.size());
  std::partial_sort(
      order.begin(), order.begin() + static_cast<long>(k), order.end(),
      [&](size_t a, size_t b) { return score[a] != score[b] ? score[a] > score[b] : a < b; });
  order.resize(k);
  return order;
}

}  // namespace

ClassicBaselines::ClassicBaselines(const std::vector<Keyframe>& keyframes,
                                   const std::vector<cv::Mat>& images) {
  if (keyframes.empty() || keyframes.size() != images.size()) {
    PLACEDB_THROW_INVALID("baselines need one image per keyframe (", images.size(), " for ",
                          keyframes.size(), ")");
  }
  height_ = HogHeightForFrame(kWidth, images.front().size());
  const bool timed = std::all_of(keyframes.begin(), keyframes.end(),
                                 [](const Keyframe& k) { return k.timestamp >= 0.0; });
  std::vector<size_t> order(keyframes.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    if (timed && keyframes[a].timestamp != keyframes[b].timestamp)
      return keyframes[a].timestamp < keyframes[b].timestamp;
    return keyframes[a].id < keyframes[b].id;
  });
  for (const size_t i : order) {
    ids_.push_back(keyframes[i].id);
    hog_.push_back(HogRow(images[i]));
    thumbnails_.push_back(Thumbnail(images[i]));
  }
}

cv::Mat ClassicBaselines::HogRow(const cv::Mat& image) const {
  cv::Mat small;
  cv::resize(ToGray(image), small, cv::Size(kWidth, height_), 0, 0, cv::INTER_AREA);
  const cv::HOGDescriptor hog(cv::Size(kWidth, height_), cv::Size(16, 16), cv::Size(8, 8),
                              cv::Size(8, 8), 9);
  std::vector<float> values;
  hog.compute(small, values);
  cv::Mat row = cv::Mat(values, true).reshape(1, 1);
  const double norm = cv::norm(row);
  if (norm > 0) row /= norm;
  return row;
}

cv::Mat ClassicBaselines::Thumbnail(const cv::Mat& image) const {
  WholeImageOptions o;
  o.width = kWidth;
  o.height = std::min(height_, 64);
  o.patch = 8;
  return ComputeWholeImageDescriptor(image, o);
}

BaselineAnswer ClassicBaselines::Hog(const cv::Mat& image) const {
  const cv::Mat q = HogRow(image);
  cv::Mat cosine = hog_ * q.t();  // n x 1
  std::vector<double> score(ids_.size());
  for (size_t i = 0; i < score.size(); ++i) score[i] = cosine.at<float>(static_cast<int>(i), 0);
  BaselineAnswer a;
  const std::vector<size_t> best = Best(score, 5);
  for (const size_t i : best) a.ranked.push_back(ids_[i]);
  a.score = score[best.front()];
  return a;
}

BaselineAnswer ClassicBaselines::SeqSlam(const cv::Mat& image) {
  const cv::Mat q = Thumbnail(image);
  const int n = static_cast<int>(ids_.size());
  const int dims = q.cols;
  // The differences to every keyframe, enhanced along the keyframe order.
  std::vector<double> d(static_cast<size_t>(n));
  const int8_t* qp = q.ptr<int8_t>();
  for (int i = 0; i < n; ++i) {
    const int8_t* t = thumbnails_.ptr<int8_t>(i);
    int64_t sum = 0;
    for (int c = 0; c < dims; ++c)
      sum += std::abs(static_cast<int>(qp[c]) - static_cast<int>(t[c]));
    d[static_cast<size_t>(i)] = static_cast<double>(sum) / dims;
  }
  const std::vector<double> z = StandardisedAlongMap(d, kSeqSlamWindow);
  std::vector<float> enhanced(z.begin(), z.end());
  differences_.push_front(std::move(enhanced));
  while (differences_.size() > static_cast<size_t>(kSeqSlamLength)) differences_.pop_back();
  // Lines ending at every keyframe: the smallest mean over the velocities.
  const size_t h = differences_.size();
  std::vector<double> score(static_cast<size_t>(n), -std::numeric_limits<double>::infinity());
  for (int v10 = 8; v10 <= 12; ++v10) {
    for (int j = 0; j < n; ++j) {
      double sum = 0;
      int used = 0;
      for (size_t k = 0; k < h; ++k) {
        const long p = j - std::lround(v10 * static_cast<double>(k) / 10.0);
        if (p < 0) break;
        sum += differences_[k][static_cast<size_t>(p)];
        ++used;
      }
      score[static_cast<size_t>(j)] = std::max(score[static_cast<size_t>(j)], -sum / used);
    }
  }
  BaselineAnswer a;
  const std::vector<size_t> best = Best(score, 5);
  for (const size_t i : best) a.ranked.push_back(ids_[i]);
  a.score = score[best.front()];
  return a;
}

}  // namespace placedb
