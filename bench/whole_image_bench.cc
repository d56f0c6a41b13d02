// The whole-image channel's hot loop: the cosine of one query thumbnail
// (32 x 24 = 768 int8 values) with 10 000 stored rows, per kernel
// (feature/whole_image.h). items_per_second counts rows. Names:
// BM_WholeImageSimilarities/<kernel>/<rows> (label: kernel name; kernel =
// WholeImageKernel value); kernels the CPU cannot run are reported as errors.
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "placedb/feature/whole_image.h"

namespace placedb {
namespace {

constexpr size_t kRows = 10000;
constexpr int kDims = 768;

std::vector<int8_t> RandomValues(size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<int8_t> v(n);
  for (int8_t& x : v) x = static_cast<int8_t>(static_cast<int>(rng() % 255) - 127);
  return v;
}

void BM_WholeImageSimilarities(benchmark::State& state) {
  const auto kernel = static_cast<WholeImageKernel>(state.range(0));
  state.SetLabel(WholeImageKernelName(kernel));
  if (!WholeImageKernelAvailable(kernel)) {
    state.SkipWithError("kernel not available on this CPU");
    return;
  }
  const std::vector<int8_t> query = RandomValues(kDims, 1);
  const size_t n = static_cast<size_t>(state.range(1));
  const std::vector<int8_t> rows = RandomValues(n * kDims, 2);
  std::vector<float> out(n);
  for (auto _ : state) {
    WholeImageSimilaritiesWith(kernel, query.data(), rows.data(), n, kDims, out.data());
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(n));
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(n) * kDims);
}
// 10 000 rows (7.7 MB: from the last-level cache or memory), and 100 rows
// (77 KB, in the core's caches: the kernel's arithmetic alone).
BENCHMARK(BM_WholeImageSimilarities)
    ->ArgsProduct({benchmark::CreateDenseRange(0, kNumWholeImageKernels - 1, 1),
                   {static_cast<int64_t>(kRows), 100}})
    ->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace placedb

BENCHMARK_MAIN();
