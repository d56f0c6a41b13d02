#include "placedb/feature/whole_image_model.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <opencv2/objdetect.hpp>

#include "placedb/image/chromaticity.h"
#include "placedb/util/check.h"

namespace placedb {
namespace {

constexpr int kBlock = 16, kStride = 8, kCell = 4, kBins = 9;
constexpr double kRawScale = 510.0;  // a byte of the raw row is round(min(v, 0.5) x 510)
constexpr double kRowScale = 32.0;   // whitened values have at most unit variance: +-4 sd

void CheckSize(int width, int height) {
  auto bad = [](int v) { return v < 16 || v > 128 || v % 8 != 0; };
  if (bad(width) || bad(height)) {
    PLACEDB_THROW_INVALID("a HOG thumbnail of ", width, " x ", height,
                          " (each side a multiple of 8 in [16, 128])");
  }
}

// splitmix64: the same bits on every platform (std's distributions are not).
uint64_t SplitMix(uint64_t* state) {
  uint64_t z = (*state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

}  // namespace

int HogRawDims(int width, int height) {
  CheckSize(width, height);
  const int blocks = ((width - kBlock) / kStride + 1) * ((height - kBlock) / kStride + 1);
  return blocks * (kBlock / kCell) * (kBlock / kCell) * kBins;
}

int HogHeightForFrame(int width, cv::Size frame) {
  if (frame.width <= 0 || frame.height <= 0) return 48;
  const double h = static_cast<double>(width) * frame.height / frame.width;
  return std::clamp(static_cast<int>(std::lround(h / 8.0)) * 8, 16, 128);
}

cv::Mat ComputeHogRaw(const cv::Mat& image, int width, int height) {
  const int dims = HogRawDims(width, height);
  if (image.empty()) PLACEDB_THROW_INVALID("the whole-image descriptor of an empty image");
  const cv::Mat gray = ToGray(image);  // InvalidArgument unless 8-bit, 1, 3 or 4 channels
  cv::Mat thumb;
  cv::resize(gray, thumb, cv::Size(width, height), 0, 0, cv::INTER_AREA);
  cv::Mat equalised;
  cv::createCLAHE(2.0, cv::Size(4, 4))->apply(thumb, equalised);
  const cv::HOGDescriptor hog(cv::Size(width, height), cv::Size(kBlock, kBlock),
                              cv::Size(kStride, kStride), cv::Size(kCell, kCell), kBins);
  std::vector<float> values;
  hog.compute(equalised, values);
  PLACEDB_CHECK(static_cast<int>(values.size()) == dims, "HOG gave ", values.size(),
                " values, expected ", dims);
  cv::Mat out(1, dims, CV_8U);
  uint8_t* row = out.ptr<uint8_t>(0);
  for (int i = 0; i < dims; ++i) {
    const double v = std::isfinite(values[i]) ? std::clamp<double>(values[i], 0.0, 0.5) : 0.0;
    row[i] = static_cast<uint8_t>(std::lround(v * kRawScale));
  }
  return out;
}

WholeImageModel::WholeImageModel(int width, int height, int output_dims, std::vector<float> mean,
                                 std::vector<float> projection)
    : width_(width),
      height_(height),
      output_dims_(output_dims),
      mean_(std::move(mean)),
      projection_(std::move(projection)) {
  const int dims = HogRawDims(width, height);
  if (output_dims < 1 || output_dims > 4096) {
    PLACEDB_THROW_INVALID("a whole-image model of ", output_dims, " values (at most 4096)");
  }
  if (static_cast<int>(mean_.size()) != dims ||
      projection_.size() != static_cast<size_t>(output_dims) * static_cast<size_t>(dims)) {
    PLACEDB_THROW_INVALID("a whole-image model's mean and projection do not fit ", width, " x ",
                          height, " thumbnails and ", output_dims, " values");
  }
  auto finite = [](float v) { return std::isfinite(v) && std::abs(v) < 1e6f; };
  if (!std::all_of(mean_.begin(), mean_.end(), finite) ||
      !std::all_of(projection_.begin(), projection_.end(), finite)) {
    PLACEDB_THROW_INVALID("a whole-image model with values that are not finite numbers below 1e6");
  }
}

WholeImageModel WholeImageModel::Fit(const std::vector<cv::Mat>& raw, int width, int height,
                                     int output_dims, uint64_t seed) {
  const int dims = HogRawDims(width, height);
  if (raw.size() < 2) PLACEDB_THROW_INVALID("a whole-image model needs 2 or more keyframes");
  if (output_dims < 1 || output_dims > 4096) {
    PLACEDB_THROW_INVALID("a whole-image model of ", output_dims, " values (at most 4096)");
  }
  for (const cv::Mat& r : raw) {
    if (r.type() != CV_8UC1 || r.rows != 1 || r.cols != dims || !r.isContinuous()) {
      PLACEDB_THROW_INVALID("a raw whole-image row that is not 1 x ", dims, " CV_8U");
    }
  }
  // At most kMaxFitRows rows, spread evenly over the map.
  const size_t n = std::min(raw.size(), kMaxFitRows);
  Eigen::MatrixXd x(static_cast<Eigen::Index>(n), dims);
  for (size_t i = 0; i < n; ++i) {
    const cv::Mat& r = raw[i * raw.size() / n];
    const uint8_t* p = r.ptr<uint8_t>(0);
    for (int d = 0; d < dims; ++d) x(static_cast<Eigen::Index>(i), d) = p[d] / kRawScale;
  }
  const Eigen::RowVectorXd mean = x.colwise().mean();
  x.rowwise() -= mean;

  // A randomised range finder with two power iterations, then the exact
  // decomposition of the small projected matrix.
  const int wanted = std::min<int>({output_dims, static_cast<int>(n) - 1, dims});
  const int k = std::min<int>(wanted + 16, std::min<int>(static_cast<int>(n), dims));
  Eigen::MatrixXd omega(dims, k);
  uint64_t state = seed;
  for (Eigen::Index c = 0; c < k; ++c)
    for (Eigen::Index r = 0; r < dims; ++r) omega(r, c) = (SplitMix(&state) >> 63) ? 1.0 : -1.0;
  auto orthonormal = [](const Eigen::MatrixXd& y) {
    Eigen::HouseholderQR<Eigen::MatrixXd> qr(y);
    return Eigen::MatrixXd(qr.householderQ() * Eigen::MatrixXd::Identity(y.rows(), y.cols()));
  };
  Eigen::MatrixXd q = orthonormal(x * omega);
  for (int it = 0; it < 2; ++it) q = orthonormal(x * (x.transpose() * q));
  const Eigen::MatrixXd b = q.transpose() * x;  // k x dims
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(b * b.transpose());
  // Components by decreasing variance; those of (numerically) no variance dropped.
  std::vector<float> projection(static_cast<size_t>(output_dims) * dims, 0.0f);
  std::vector<double> variance;
  std::vector<Eigen::VectorXd> components;
  for (int i = k - 1; i >= 0 && static_cast<int>(components.size()) < wanted; --i) {
    const double lambda = eig.eigenvalues()(i);
    if (!(lambda > 1e-12)) break;
    Eigen::VectorXd v = b.transpose() * eig.eigenvectors().col(i) / std::sqrt(lambda);
    // A sign of our own: the largest entry positive.
    Eigen::Index at = 0;
    v.cwiseAbs().maxCoeff(&at);
    if (v(at) < 0) v = -v;
    components.push_back(v);
    variance.push_back(lambda / static_cast<double>(n));
  }
  double mean_variance = 0.0;
  for (const double v : variance) mean_variance += v;
  if (!variance.empty()) mean_variance /= static_cast<double>(variance.size());
  for (size_t c = 0; c < components.size(); ++c) {
    const double w = 1.0 / std::sqrt(variance[c] + mean_variance);
    for (int d = 0; d < dims; ++d)
      projection[c * dims + d] = static_cast<float>(components[c](d) * w);
  }
  std::vector<float> mean_out(dims);
  for (int d = 0; d < dims; ++d) mean_out[d] = static_cast<float>(mean(d));
  return WholeImageModel(width, height, output_dims, std::move(mean_out), std::move(projection));
}

cv::Mat WholeImageModel::Project(const cv::Mat& raw) const {
  const int dims = input_dims();
  if (raw.type() != CV_8UC1 || raw.rows != 1 || raw.cols != dims || !raw.isContinuous()) {
    PLACEDB_THROW_INVALID("a raw whole-image row that is not 1 x ", dims, " CV_8U");
  }
  const uint8_t* p = raw.ptr<uint8_t>(0);
  Eigen::VectorXf centred(dims);
  for (int d = 0; d < dims; ++d) centred(d) = static_cast<float>(p[d] / kRawScale) - mean_[d];
  const Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> w(
      projection_.data(), output_dims_, dims);
  const Eigen::VectorXf y = w * centred;
  cv::Mat out(1, output_dims_, CV_8S);
  int8_t* row = out.ptr<int8_t>(0);
  for (int i = 0; i < output_dims_; ++i) {
    const double v = std::clamp(static_cast<double>(y(i)) * kRowScale, -127.0, 127.0);
    row[i] = static_cast<int8_t>(std::lround(v));
  }
  return out;
}

cv::Mat WholeImageModel::Describe(const cv::Mat& image) const {
  return Project(ComputeHogRaw(image, width_, height_));
}

}  // namespace placedb
