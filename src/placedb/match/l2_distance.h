// Squared Euclidean distance between float vectors (SURF descriptors): a
// plain reference loop and the fastest kernel for the running CPU (AVX2+FMA
// when available, chosen once at run time; else SSE2 on x86-64; else plain).
#pragma once

#include <cstdint>

#include "placedb/match/two_nearest.h"

namespace placedb {

// Squared L2 distance between a[0..n) and b[0..n); plain loop. n >= 0.
float L2SquaredReference(const float* a, const float* b, int n);

// Same value as L2SquaredReference up to float rounding (the SIMD kernels sum
// in a different order); any n >= 0, no alignment required.
float L2Squared(const float* a, const float* b, int n);

// The two smallest squared distances from `query` (dims floats) to `count`
// vectors stored back to back at `db`, and the index of the smallest (ties:
// lower index). With `signs` (one +1/-1 per db row), only rows whose sign
// equals `query_sign` are compared (SURF's Laplacian test). No candidate:
// both distances are +infinity and best_index is -1.
using TwoNearestL2Result = TwoNearestOf<float>;
TwoNearestL2Result TwoNearestL2Reference(const float* query, const float* db, int count, int dims,
                                         const int8_t* signs, int8_t query_sign);
// The same with the fastest kernel for this CPU (AVX2+FMA: four rows per
// step, the query held in registers for 64 and 128 dims).
TwoNearestL2Result TwoNearestL2(const float* query, const float* db, int count, int dims,
                                const int8_t* signs, int8_t query_sign);

// Name of the kernel L2Squared uses on this CPU: "avx2+fma", "sse2" or "plain".
const char* L2SquaredKernelName();

}  // namespace placedb
