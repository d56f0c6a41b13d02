// Micro-benchmarks of the matching kernels: the two nearest Hamming
// neighbours of a query descriptor among a keyframe's 500 ORB descriptors,
// per kernel, next to OpenCV's BFMatcher doing the same work (knnMatch, k=2),
// and the L2 kernels for SURF.
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
  state.SetLabel(kernel == HammingKernel::kAvx2     ? "avx2"
                 : kernel == HammingKernel::kPopcnt ? "popcnt"
                                                    : "reference");
}
BENCHMARK(BM_TwoNearestHamming)
    ->Arg(static_cast<int>(HammingKernel::kReference))
    ->Arg(static_cast<int>(HammingKernel::kPopcnt))
    ->Arg(static_cast<int>(HammingKernel::kAvx2));

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
  state.SetLabel(reference ? "reference" : L2SquaredKernelName());
}
BENCHMARK(BM_L2Squared)->Args({64, 1})->Args({64, 0})->Args({128, 1})->Args({128, 0});

}  // namespace
}  // namespace placedb

BENCHMARK_MAIN();
