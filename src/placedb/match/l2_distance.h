// Squared Euclidean distance between float vectors (SURF descriptors): a
// plain reference loop and the fastest kernel for the running CPU (AVX2+FMA
// when available, chosen once at run time; else SSE2 on x86-64; else plain).
#pragma once

namespace placedb {

// Squared L2 distance between a[0..n) and b[0..n); plain loop. n >= 0.
float L2SquaredReference(const float* a, const float* b, int n);

// Same value as L2SquaredReference up to float rounding (the SIMD kernels sum
// in a different order); any n >= 0, no alignment required.
float L2Squared(const float* a, const float* b, int n);

// Name of the kernel L2Squared uses on this CPU: "avx2+fma", "sse2" or "plain".
const char* L2SquaredKernelName();

}  // namespace placedb
