// Micro-benchmarks of the matching kernels: the two nearest Hamming
// neighbours of each of 500 query descriptors among a keyframe's 500 ORB
// descriptors, per kernel, next to OpenCV's BFMatcher doing the same work
// (knnMatch, k=2), and the L2 kernels for SURF (64 and 128 dims).
//
// items_per_second counts distances, so ns per distance = 1e9 /
// items_per_second. Names: BM_TwoNearestHamming/<kernel> (label: kernel
// name; kernel = HammingKernel value), BM_BfMatcherKnnHamming,
// BM_TwoNearestL2/<dims>/<kernel> (label: kernel name; kernel = L2Kernel
// value) and BM_SignsTwoNearestL2/<dims>/<kernel>, the same with SURF's
// Laplacian signs (about half the rows compared; items = rows compared).
// Kernels the CPU cannot run are reported as errors ("not available").
#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <random>
#include <vector>

#include "placedb/match/hamming.h"
#include "placedb/match/l2_distance.h"

namespace placedb {
namespace {

constexpr int kQueries = 500;
constexpr int kTrain = 500;

cv::Mat RandomBinary(int rows, uint32_t seed) {
  cv::Mat m(rows, 32, CV_8U);
  cv::RNG rng(seed);
  rng.fill(m, cv::RNG::UNIFORM, 0, 256);
  return m;
}

void BM_TwoNearestHamming(benchmark::State& state) {
  const auto kernel = static_cast<HammingKernel>(state.range(0));
  state.SetLabel(HammingKernelName(kernel));
  if (!HammingKernelAvailable(kernel)) {
    state.SkipWithError("kernel not available on this CPU");
    return;
  }
  const cv::Mat q = RandomBinary(kQueries, 1), t = RandomBinary(kTrain, 2);
  for (auto _ : state) {
    uint32_t sum = 0;
    for (int i = 0; i < kQueries; ++i) {
      sum += TwoNearestHammingWith(kernel, q.ptr<uint8_t>(i), t.ptr<uint8_t>(), kTrain, 32).best;
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * kQueries * kTrain);
}
BENCHMARK(BM_TwoNearestHamming)->DenseRange(0, kNumHammingKernels - 1);

void BM_BfMatcherKnnHamming(benchmark::State& state) {
  cv::setNumThreads(1);
  const cv::Mat q = RandomBinary(kQueries, 1), t = RandomBinary(kTrain, 2);
  cv::BFMatcher matcher(cv::NORM_HAMMING);
  std::vector<std::vector<cv::DMatch>> knn;
  for (auto _ : state) {
    matcher.knnMatch(q, t, knn, 2);
    benchmark::DoNotOptimize(knn.data());
  }
  state.SetItemsProcessed(state.iterations() * kQueries * kTrain);
}
BENCHMARK(BM_BfMatcherKnnHamming);

// SURF-like data: 500 queries x 500 database rows of `dims` floats, and one
// Laplacian sign per row (about half the rows share a query's sign).
struct SurfData {
  std::vector<float> queries, db;
  std::vector<int8_t> query_signs, db_signs;
  explicit SurfData(int dims) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-0.2f, 0.2f);
    queries.resize(static_cast<size_t>(kQueries) * dims);
    db.resize(static_cast<size_t>(kTrain) * dims);
    for (auto& x : queries) x = u(rng);
    for (auto& x : db) x = u(rng);
    for (int i = 0; i < kQueries; ++i) query_signs.push_back((rng() & 1) ? 1 : -1);
    for (int i = 0; i < kTrain; ++i) db_signs.push_back((rng() & 1) ? 1 : -1);
  }
};

void RunTwoNearestL2(benchmark::State& state, bool with_signs) {
  const int dims = static_cast<int>(state.range(0));
  const auto kernel = static_cast<L2Kernel>(state.range(1));
  state.SetLabel(L2KernelName(kernel));
  if (!L2KernelAvailable(kernel)) {
    state.SkipWithError("kernel not available on this CPU");
    return;
  }
  const SurfData data(dims);
  int64_t compared = 0;  // distances actually computed per iteration
  for (int i = 0; i < kQueries; ++i) {
    for (int j = 0; j < kTrain; ++j) {
      compared += !with_signs || data.db_signs[j] == data.query_signs[i];
    }
  }
  for (auto _ : state) {
    float sum = 0;
    for (int i = 0; i < kQueries; ++i) {
      sum += TwoNearestL2With(kernel, data.queries.data() + static_cast<size_t>(i) * dims,
                              data.db.data(), kTrain, dims,
                              with_signs ? data.db_signs.data() : nullptr, data.query_signs[i])
                 .best;
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * compared);
}

void BM_TwoNearestL2(benchmark::State& state) { RunTwoNearestL2(state, false); }
void BM_SignsTwoNearestL2(benchmark::State& state) { RunTwoNearestL2(state, true); }
BENCHMARK(BM_TwoNearestL2)
    ->ArgsProduct({{64, 128}, benchmark::CreateDenseRange(0, kNumL2Kernels - 1, 1)});
BENCHMARK(BM_SignsTwoNearestL2)
    ->ArgsProduct({{64, 128}, benchmark::CreateDenseRange(0, kNumL2Kernels - 1, 1)});

// One distance at a time (L2Squared, the active kernel) vs the reference.
void BM_L2Squared(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const bool reference = state.range(1) != 0;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<float> a(static_cast<size_t>(n) * 256), b(n);
  for (auto& x : a) x = u(rng);
  for (auto& x : b) x = u(rng);
  for (auto _ : state) {
    float sum = 0;
    for (int j = 0; j < 256; ++j) {
      sum += reference ? L2SquaredReference(b.data(), a.data() + j * n, n)
                       : L2Squared(b.data(), a.data() + j * n, n);
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * 256);
  state.SetLabel(reference ? "reference" : L2KernelName());
}
BENCHMARK(BM_L2Squared)->Args({64, 1})->Args({64, 0})->Args({128, 1})->Args({128, 0});

}  // namespace
}  // namespace placedb

BENCHMARK_MAIN();
