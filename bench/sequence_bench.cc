// The sequence step and the whole-image comparison at 10 000 and 100 000
// keyframes, each beside its baseline measured in the same run:
//   BM_SequenceFeed/<keyframes>/<whole map>: SequenceMatcher::Feed of one
//     frame with 10 frames held and the default 9 velocities; whole map 0
//     is today's matcher on each frame's ranked list (the baseline), 1 the
//     search over the whole map (Feed with similarities, every end x
//     velocity scored).
//   BM_HogSimilarities/<keyframes>: the cosine of one query row with every
//     keyframe's row (the dispatched kernel), 512 values (the HOG channel's
//     rows) beside 768 (the thumbnail's, the baseline).
// Inputs are seeded random values: the work does not depend on them.
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "placedb/feature/whole_image.h"
#include "placedb/query/sequence.h"

namespace placedb {
namespace {

std::vector<Keyframe> Keyframes(size_t n) {
  std::vector<Keyframe> k(n);
  for (size_t i = 0; i < n; ++i) {
    k[i].id = static_cast<int32_t>(i + 1);
    k[i].timestamp = static_cast<double>(i);
  }
  return k;
}

QueryResult Ranked(std::mt19937_64& rng, size_t n) {
  QueryResult r;
  for (int i = 0; i < 5; ++i) {
    RankedKeyframe k;
    k.keyframe_id = static_cast<int32_t>(rng() % n + 1);
    k.score = static_cast<double>(rng() % 30);
    r.ranked.push_back(k);
  }
  return r;
}

void BM_SequenceFeed(benchmark::State& state) {
  const auto n = static_cast<size_t>(state.range(0));
  const bool whole_map = state.range(1) != 0;
  SequenceOptions options;
  options.whole_image_weight = whole_map ? 10.0 : 0.0;
  SequenceMatcher matcher(Keyframes(n), options);
  std::mt19937_64 rng(1);
  std::normal_distribution<float> noise(0.3f, 0.05f);
  // A few distinct frames, fed in turn, so the matcher always holds 10.
  std::vector<QueryResult> frames;
  std::vector<std::vector<float>> similarities;
  for (int f = 0; f < 4; ++f) {
    frames.push_back(Ranked(rng, n));
    std::vector<float> s(n);
    for (float& v : s) v = noise(rng);
    similarities.push_back(std::move(s));
  }
  const std::vector<float> none;
  for (int i = 0; i < options.length; ++i) {
    matcher.Feed(frames[static_cast<size_t>(i) % 4], whole_map ? similarities[0] : none);
  }
  size_t i = 0;
  for (auto _ : state) {
    QueryResult r = matcher.Feed(frames[i % 4], whole_map ? similarities[i % 4] : none);
    benchmark::DoNotOptimize(r);
    ++i;
  }
  state.SetLabel(whole_map ? "whole map" : "ranked lists");
}
BENCHMARK(BM_SequenceFeed)->ArgsProduct({{10000, 100000}, {0, 1}})->Unit(benchmark::kMillisecond);

void BM_HogSimilarities(benchmark::State& state) {
  const auto n = static_cast<size_t>(state.range(0));
  const auto dims = static_cast<int>(state.range(1));
  std::mt19937_64 rng(2);
  std::vector<int8_t> rows(n * static_cast<size_t>(dims)), query(static_cast<size_t>(dims));
  for (int8_t& v : rows) v = static_cast<int8_t>(static_cast<int>(rng() % 255) - 127);
  for (int8_t& v : query) v = static_cast<int8_t>(static_cast<int>(rng() % 255) - 127);
  std::vector<float> out(n);
  for (auto _ : state) {
    WholeImageSimilarities(query.data(), rows.data(), n, dims, out.data());
    benchmark::DoNotOptimize(out.data());
    benchmark::ClobberMemory();
  }
  state.SetLabel(dims == 512 ? "hog rows" : "thumbnail rows");
  state.SetBytesProcessed(state.iterations() * static_cast<int64_t>(n) * dims);
}
BENCHMARK(BM_HogSimilarities)
    ->ArgsProduct({{10000, 100000}, {512, 768}})
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace placedb

BENCHMARK_MAIN();
