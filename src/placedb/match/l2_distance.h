// Squared Euclidean distance between float vectors (SURF descriptors): a
// plain reference loop and SIMD kernels (SSE2, AVX2+FMA, AVX-512). The one
// L2Squared / TwoNearestL2 use is chosen once, on first use, from the CPU's
// features, unless the environment variable PLACEDB_L2_KERNEL
// (reference|sse2|avx2|avx512) names another kernel the CPU can run.
#pragma once

#include <cstdint>
#include <optional>

#include "placedb/match/two_nearest.h"

namespace placedb {

// Squared L2 distance between a[0..n) and b[0..n); plain loop. n >= 0.
float L2SquaredReference(const float* a, const float* b, int n);

// Same value as L2SquaredReference up to float rounding (the SIMD kernels sum
// in a different order); any n >= 0, no alignment required.
float L2Squared(const float* a, const float* b, int n);

// The two smallest squared distances from `query` (dims floats) to `count`
// vectors stored back to back at `db`, and the index of the smallest (ties:
// lower index, so `second == best` when two rows tie at the minimum). With
// `signs` (one +1/-1 per db row), only rows whose sign equals `query_sign`
// are compared (SURF's Laplacian test). No candidate: both distances are
// +infinity and best_index is -1.
using TwoNearestL2Result = TwoNearestOf<float>;
TwoNearestL2Result TwoNearestL2Reference(const float* query, const float* db, int count, int dims,
                                         const int8_t* signs, int8_t query_sign);
// The same with ActiveL2Kernel().
TwoNearestL2Result TwoNearestL2(const float* query, const float* db, int count, int dims,
                                const int8_t* signs, int8_t query_sign);

// The kernels, for tests and benchmarks. The numeric values are stable
// (benchmark arguments).
//   kReference: plain loops, any CPU.
//   kSse2:      SSE2, one row at a time.
//   kAvx2:      AVX2+FMA; 64 and 128 dims with the query in registers.
//   kAvx512:    AVX-512 (F, BW, VL); 64 and 128 dims 16 rows per step with
//               vector best/second tracking and, with signs, the rows of
//               the query's sign gathered first. Other dims: one row at a
//               time.
enum class L2Kernel { kReference = 0, kSse2 = 1, kAvx2 = 2, kAvx512 = 3 };
constexpr int kNumL2Kernels = 4;

// Whether this CPU (and OS) can run `kernel`.
bool L2KernelAvailable(L2Kernel kernel);

// L2Squared / TwoNearestL2 with the given kernel; a kernel this CPU cannot
// run is replaced by the reference one (never executes unsupported
// instructions).
float L2SquaredWith(L2Kernel kernel, const float* a, const float* b, int n);
TwoNearestL2Result TwoNearestL2With(L2Kernel kernel, const float* query, const float* db, int count,
                                    int dims, const int8_t* signs, int8_t query_sign);

// The fastest kernel this CPU runs, ignoring the environment.
L2Kernel BestL2Kernel();

// The kernel L2Squared / TwoNearestL2 use: ChooseL2Kernel(getenv(
// "PLACEDB_L2_KERNEL")), evaluated once on first use.
L2Kernel ActiveL2Kernel();

// The rule behind ActiveL2Kernel: `requested` (may be null or empty: no
// request) names a kernel; if the name is unknown or the CPU cannot run that
// kernel, logs one warning and returns BestL2Kernel().
L2Kernel ChooseL2Kernel(const char* requested);

// "reference", "sse2", "avx2", "avx512" <-> kernel. Unknown names (or
// null): std::nullopt.
const char* L2KernelName(L2Kernel kernel);
std::optional<L2Kernel> L2KernelFromName(const char* name);

// Name of ActiveL2Kernel() ("reference", "sse2", "avx2", "avx512").
const char* L2KernelName();

}  // namespace placedb
