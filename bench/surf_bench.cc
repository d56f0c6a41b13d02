// SURF (ours) vs OpenCV SIFT and ORB: detect + describe time on one thread.
//   surf_bench [--benchmark_filter=...]
// BM_Surf* use the SIMD level chosen at run time from the CPU (printed in the
// context as surf_simd); BM_SurfPlain is BM_Surf forced onto the plain
// (baseline) copy of the hot loops, so one run shows what the dispatch buys.
// Images: a 640x480 TUM frame and graf1 (800x640), read from PLACEDB_DATA_DIR.
#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "placedb/feature/surf/surf.h"
#include "placedb/feature/surf/surf_simd.h"
#include "placedb/util/check.h"

namespace {

const char* const kImages[] = {
    "/tum_fr3_office_mini/rgb/1341847980.722988.png",  // 640 x 480.
    "/oxford_graf/graf1.png",                          // 800 x 640.
};

const cv::Mat& Image(int index) {
  static const cv::Mat images[2] = {
      cv::imread(std::string(PLACEDB_DATA_DIR) + kImages[0], cv::IMREAD_GRAYSCALE),
      cv::imread(std::string(PLACEDB_DATA_DIR) + kImages[1], cv::IMREAD_GRAYSCALE),
  };
  if (images[index].empty())
    PLACEDB_THROW_NOT_FOUND("cannot read ", PLACEDB_DATA_DIR, kImages[index]);
  return images[index];
}

void Run(benchmark::State& state, cv::Feature2D& features) {
  cv::setNumThreads(1);
  const cv::Mat& img = Image(static_cast<int>(state.range(0)));
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  for (auto _ : state) {
    features.detectAndCompute(img, cv::noArray(), keypoints, descriptors);
    benchmark::DoNotOptimize(descriptors.data);
  }
  state.counters["keypoints"] = static_cast<double>(keypoints.size());
  state.SetLabel(state.range(0) == 0 ? "tum 640x480" : "graf1 800x640");
}

void BM_Surf(benchmark::State& state) {
  placedb::SurfFeature2D surf;
  Run(state, surf);
}

void BM_SurfPlain(benchmark::State& state) {
  const bool was = placedb::surf_internal::SetSurfSimdForTesting(false);
  placedb::SurfFeature2D surf;
  Run(state, surf);
  placedb::surf_internal::SetSurfSimdForTesting(was);
}

void BM_SurfUpright(benchmark::State& state) {
  placedb::SurfOptions options;
  options.upright = true;
  placedb::SurfFeature2D surf(options);
  Run(state, surf);
}

void BM_SurfDetectOnly(benchmark::State& state) {
  cv::setNumThreads(1);
  const cv::Mat& img = Image(static_cast<int>(state.range(0)));
  std::vector<cv::KeyPoint> keypoints;
  for (auto _ : state) {
    placedb::DetectSurf(img, placedb::SurfOptions(), &keypoints);
    benchmark::DoNotOptimize(keypoints.data());
  }
  state.counters["keypoints"] = static_cast<double>(keypoints.size());
}

void BM_Sift(benchmark::State& state) {
  const cv::Ptr<cv::SIFT> sift = cv::SIFT::create();
  Run(state, *sift);
}

void BM_Orb(benchmark::State& state) {
  const cv::Ptr<cv::ORB> orb = cv::ORB::create();
  Run(state, *orb);
}

BENCHMARK(BM_Surf)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SurfPlain)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SurfUpright)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SurfDetectOnly)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Sift)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Orb)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
  benchmark::AddCustomContext("surf_simd", placedb::surf_internal::SurfSimdName(
                                               placedb::surf_internal::SurfSimdSupported()));
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
