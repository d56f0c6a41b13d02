// The HOG whole-image descriptor and its model: sizes, determinism, what the
// projection does to the map it was fitted on, against an exact PCA.
#include "placedb/feature/whole_image_model.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "placedb/feature/whole_image.h"
#include "placedb/util/check.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {

using testing_util::RtabmapImage;
using testing_util::ThrowsWith;

double Cosine(const cv::Mat& a, const cv::Mat& b) {
  return WholeImageSimilarity(a.ptr<int8_t>(), b.ptr<int8_t>(), a.cols);
}

TEST(HogWholeImageTest, SizesAndDeterminism) {
  EXPECT_EQ(HogRawDims(64, 48), 5040);
  EXPECT_EQ(HogRawDims(64, 32), 3024);
  EXPECT_EQ(HogRawDims(16, 16), 144);
  EXPECT_EQ(HogHeightForFrame(64, cv::Size(512, 384)), 48);
  EXPECT_EQ(HogHeightForFrame(64, cv::Size(64, 32)), 32);
  EXPECT_EQ(HogHeightForFrame(64, cv::Size(640, 480)), 48);
  EXPECT_EQ(HogHeightForFrame(64, cv::Size(1000, 10)), 16);
  EXPECT_EQ(HogHeightForFrame(64, cv::Size(10, 1000)), 128);
  for (const auto& [w, h] : {std::pair{12, 48}, {64, 20}, {136, 48}, {64, 0}}) {
    EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { HogRawDims(w, h); }, "multiple of 8"));
  }
  const cv::Mat image = cv::imread(RtabmapImage(5));
  const cv::Mat raw = ComputeHogRaw(image, 64, 48);
  ASSERT_EQ(raw.type(), CV_8UC1);
  ASSERT_EQ(raw.cols, 5040);
  EXPECT_EQ(cv::norm(raw, ComputeHogRaw(image, 64, 48), cv::NORM_INF), 0);
  cv::Mat gray;
  cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(cv::norm(raw, ComputeHogRaw(gray, 64, 48), cv::NORM_INF), 0);
  EXPECT_GT(cv::countNonZero(raw), 1000);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ComputeHogRaw(cv::Mat(), 64, 48); }, "empty"));
}

// The model fitted on the map: its rows have the fixed length; a keyframe's
// row is nearer to its own image darkened (an affine change of the grey
// levels) than to other keyframes; the same rows give the same model; rows
// beyond the components a small map has are 0.
TEST(HogWholeImageTest, ModelFittedOnTheMap) {
  std::vector<cv::Mat> images, raw;
  for (int i = 1; i <= 30; ++i) {
    images.push_back(cv::imread(RtabmapImage(i)));
    raw.push_back(ComputeHogRaw(images.back(), 64, 48));
  }
  const WholeImageModel model = WholeImageModel::Fit(raw, 64, 48, 64);
  EXPECT_EQ(model.input_dims(), 5040);
  EXPECT_EQ(model.output_dims(), 64);
  std::vector<cv::Mat> rows;
  for (const cv::Mat& r : raw) {
    rows.push_back(model.Project(r));
    ASSERT_EQ(rows.back().type(), CV_8SC1);
    ASSERT_EQ(rows.back().cols, 64);
    // 30 keyframes: 29 components, the rest of the row 0.
    for (int d = 29; d < 64; ++d) EXPECT_EQ(rows.back().at<int8_t>(0, d), 0);
  }
  int nearest_is_itself = 0;
  for (size_t i = 0; i < images.size(); ++i) {
    cv::Mat darker;
    images[i].convertTo(darker, -1, 0.6, 10);
    const cv::Mat q = model.Describe(darker);
    size_t best = 0;
    for (size_t j = 1; j < rows.size(); ++j) {
      if (Cosine(q, rows[j]) > Cosine(q, rows[best])) best = j;
    }
    nearest_is_itself += best == i;
  }
  EXPECT_GE(nearest_is_itself, 28);
  const WholeImageModel again = WholeImageModel::Fit(raw, 64, 48, 64);
  EXPECT_EQ(again.projection(), model.projection());
  EXPECT_EQ(again.mean(), model.mean());
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { WholeImageModel::Fit({raw[0]}, 64, 48, 64); },
                                          "2 or more keyframes"));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] {
        WholeImageModel::Fit({raw[0], ComputeHogRaw(images[1], 64, 32)}, 64, 48, 64);
      },
      "1 x 5040"));
}

// The randomised decomposition finds the principal components an exact one
// finds: on rows of a known low-rank structure plus noise, the whitened
// projections of the rows have the exact PCA's variances (each
// var / (var + mean var)), component by component.
TEST(HogWholeImageTest, RandomisedComponentsAreTheExactOnes) {
  const int dims = HogRawDims(32, 16);  // 756
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  const int n = 400, rank = 12;
  Eigen::MatrixXd basis(rank, dims);
  for (int r = 0; r < rank; ++r)
    for (int d = 0; d < dims; ++d) basis(r, d) = normal(rng);
  std::vector<cv::Mat> raw;
  Eigen::MatrixXd x(n, dims);
  for (int i = 0; i < n; ++i) {
    Eigen::RowVectorXd v = Eigen::RowVectorXd::Constant(dims, 100.0);
    for (int r = 0; r < rank; ++r) v += basis.row(r) * normal(rng) * (3.0 * (rank - r));
    for (int d = 0; d < dims; ++d) v(d) += normal(rng);
    cv::Mat row(1, dims, CV_8U);
    for (int d = 0; d < dims; ++d) {
      row.at<uint8_t>(0, d) = static_cast<uint8_t>(std::clamp(std::lround(v(d)), 0L, 255L));
      x(i, d) = row.at<uint8_t>(0, d) / 510.0;
    }
    raw.push_back(row);
  }
  const WholeImageModel model = WholeImageModel::Fit(raw, 32, 16, 8);
  x.rowwise() -= x.colwise().mean();
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> exact(x.transpose() * x / n);
  std::vector<double> var(8);
  double mean_var = 0.0;
  for (int c = 0; c < 8; ++c) mean_var += var[c] = exact.eigenvalues()(dims - 1 - c);
  mean_var /= 8;
  const Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> w(
      model.projection().data(), 8, dims);
  const Eigen::MatrixXd y = x * w.cast<double>().transpose();
  for (int c = 0; c < 8; ++c) {
    const double got = y.col(c).squaredNorm() / n;
    EXPECT_NEAR(got, var[c] / (var[c] + mean_var), 1e-3) << "component " << c;
  }
}

}  // namespace
}  // namespace placedb
