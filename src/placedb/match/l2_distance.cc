#include "placedb/match/l2_distance.h"

#include <limits>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define PLACEDB_L2_X86 1
#endif

namespace placedb {
namespace {

using L2Kernel = float (*)(const float*, const float*, int);

#if defined(PLACEDB_L2_X86)

__attribute__((target("avx2,fma"))) float L2SquaredAvx2(const float* a, const float* b, int n) {
  __m256 acc0 = _mm256_setzero_ps();
  __m256 acc1 = _mm256_setzero_ps();
  int i = 0;
  for (; i + 16 <= n; i += 16) {
    const __m256 d0 = _mm256_sub_ps(_mm256_loadu_ps(a + i), _mm256_loadu_ps(b + i));
    const __m256 d1 = _mm256_sub_ps(_mm256_loadu_ps(a + i + 8), _mm256_loadu_ps(b + i + 8));
    acc0 = _mm256_fmadd_ps(d0, d0, acc0);
    acc1 = _mm256_fmadd_ps(d1, d1, acc1);
  }
  if (i + 8 <= n) {
    const __m256 d0 = _mm256_sub_ps(_mm256_loadu_ps(a + i), _mm256_loadu_ps(b + i));
    acc0 = _mm256_fmadd_ps(d0, d0, acc0);
    i += 8;
  }
  acc0 = _mm256_add_ps(acc0, acc1);
  __m128 s = _mm_add_ps(_mm256_castps256_ps128(acc0), _mm256_extractf128_ps(acc0, 1));
  s = _mm_add_ps(s, _mm_movehl_ps(s, s));
  s = _mm_add_ss(s, _mm_shuffle_ps(s, s, 1));
  float sum = _mm_cvtss_f32(s);
  for (; i < n; ++i) {
    const float d = a[i] - b[i];
    sum += d * d;
  }
  return sum;
}

float L2SquaredSse2(const float* a, const float* b, int n) {
  __m128 acc0 = _mm_setzero_ps();
  __m128 acc1 = _mm_setzero_ps();
  int i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m128 d0 = _mm_sub_ps(_mm_loadu_ps(a + i), _mm_loadu_ps(b + i));
    const __m128 d1 = _mm_sub_ps(_mm_loadu_ps(a + i + 4), _mm_loadu_ps(b + i + 4));
    acc0 = _mm_add_ps(acc0, _mm_mul_ps(d0, d0));
    acc1 = _mm_add_ps(acc1, _mm_mul_ps(d1, d1));
  }
  if (i + 4 <= n) {
    const __m128 d0 = _mm_sub_ps(_mm_loadu_ps(a + i), _mm_loadu_ps(b + i));
    acc0 = _mm_add_ps(acc0, _mm_mul_ps(d0, d0));
    i += 4;
  }
  __m128 s = _mm_add_ps(acc0, acc1);
  s = _mm_add_ps(s, _mm_movehl_ps(s, s));
  s = _mm_add_ss(s, _mm_shuffle_ps(s, s, 1));
  float sum = _mm_cvtss_f32(s);
  for (; i < n; ++i) {
    const float d = a[i] - b[i];
    sum += d * d;
  }
  return sum;
}

#endif  // PLACEDB_L2_X86

// Scans every candidate with one distance kernel (reference or SIMD).
TwoNearestL2Result TwoNearestWithKernel(L2Kernel kernel, const float* query, const float* db,
                                        int count, int dims, const int8_t* signs,
                                        int8_t query_sign) {
  TwoNearestL2Result out;
  for (int j = 0; j < count; ++j) {
    if (signs != nullptr && signs[j] != query_sign) continue;
    out.Update(kernel(query, db + static_cast<size_t>(j) * dims, dims), j);
  }
  return out;
}

#if defined(PLACEDB_L2_X86)

__attribute__((target("avx2,fma"))) inline float HorizontalSum(__m256 v) {
  __m128 s = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
  s = _mm_add_ps(s, _mm_movehl_ps(s, s));
  s = _mm_add_ss(s, _mm_shuffle_ps(s, s, 1));
  return _mm_cvtss_f32(s);
}

// Query of kBlocks x 8 floats kept in registers; each database row is read
// once, straight from memory.
template <int kBlocks>
__attribute__((target("avx2,fma"))) TwoNearestL2Result TwoNearestAvx2Fixed(
    const float* query, const float* db, int count, const int8_t* signs, int8_t query_sign) {
  constexpr int kDims = kBlocks * 8;
  __m256 q[kBlocks];
  for (int b = 0; b < kBlocks; ++b) q[b] = _mm256_loadu_ps(query + 8 * b);
  TwoNearestL2Result out;
  for (int j = 0; j < count; ++j) {
    if (signs != nullptr && signs[j] != query_sign) continue;
    const float* row = db + static_cast<size_t>(j) * kDims;
    __m256 acc0 = _mm256_setzero_ps();
    __m256 acc1 = _mm256_setzero_ps();
    for (int b = 0; b < kBlocks; b += 2) {
      const __m256 d0 = _mm256_sub_ps(q[b], _mm256_loadu_ps(row + 8 * b));
      const __m256 d1 = _mm256_sub_ps(q[b + 1], _mm256_loadu_ps(row + 8 * b + 8));
      acc0 = _mm256_fmadd_ps(d0, d0, acc0);
      acc1 = _mm256_fmadd_ps(d1, d1, acc1);
    }
    out.Update(HorizontalSum(_mm256_add_ps(acc0, acc1)), j);
  }
  return out;
}

#endif  // PLACEDB_L2_X86

struct Dispatch {
  L2Kernel kernel = L2SquaredReference;
  const char* name = "plain";
  Dispatch() {
#if defined(PLACEDB_L2_X86)
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) {
      kernel = L2SquaredAvx2;
      name = "avx2+fma";
    } else if (__builtin_cpu_supports("sse2")) {
      kernel = L2SquaredSse2;
      name = "sse2";
    }
#endif
  }
};

const Dispatch& GetDispatch() {
  static const Dispatch dispatch;
  return dispatch;
}

}  // namespace

float L2SquaredReference(const float* a, const float* b, int n) {
  float sum = 0.f;
  for (int i = 0; i < n; ++i) {
    const float d = a[i] - b[i];
    sum += d * d;
  }
  return sum;
}

float L2Squared(const float* a, const float* b, int n) { return GetDispatch().kernel(a, b, n); }

TwoNearestL2Result TwoNearestL2Reference(const float* query, const float* db, int count, int dims,
                                         const int8_t* signs, int8_t query_sign) {
  return TwoNearestWithKernel(L2SquaredReference, query, db, count, dims, signs, query_sign);
}

TwoNearestL2Result TwoNearestL2(const float* query, const float* db, int count, int dims,
                                const int8_t* signs, int8_t query_sign) {
#if defined(PLACEDB_L2_X86)
  if (GetDispatch().kernel == L2SquaredAvx2) {
    if (dims == 64) return TwoNearestAvx2Fixed<8>(query, db, count, signs, query_sign);
    if (dims == 128) return TwoNearestAvx2Fixed<16>(query, db, count, signs, query_sign);
  }
#endif
  return TwoNearestWithKernel(GetDispatch().kernel, query, db, count, dims, signs, query_sign);
}

const char* L2SquaredKernelName() { return GetDispatch().name; }

}  // namespace placedb
