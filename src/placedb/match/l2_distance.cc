#include "placedb/match/l2_distance.h"

#include "placedb/match/kernel_choice.h"

#if defined(__x86_64__) || defined(__i386__)
// GCC 12's AVX-512 headers trip -Wuninitialized on their own
// _mm512_undefined_*() (GCC bug 105593); the warnings point into the
// header, so they are silenced for it alone.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <immintrin.h>
#pragma GCC diagnostic pop
#define PLACEDB_L2_X86 1
#endif

#include <spdlog/spdlog.h>

#include <cstdlib>
#include <cstring>
#include <limits>

namespace placedb {
namespace {

using DistanceFn = float (*)(const float*, const float*, int);

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
  // Explicit, not left to the compiler (GCC inserts it only from -O2 on).
  _mm256_zeroupper();
  for (; i < n; ++i) {
    const float d = a[i] - b[i];
    sum += d * d;
  }
  return sum;
}

__attribute__((target("sse2"))) float L2SquaredSse2(const float* a, const float* b, int n) {
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
TwoNearestL2Result TwoNearestWithKernel(DistanceFn kernel, const float* query, const float* db,
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
  _mm256_zeroupper();
  return out;
}

TwoNearestL2Result TwoNearestAvx2(const float* query, const float* db, int count, int dims,
                                  const int8_t* signs, int8_t query_sign) {
  if (dims == 64) return TwoNearestAvx2Fixed<8>(query, db, count, signs, query_sign);
  if (dims == 128) return TwoNearestAvx2Fixed<16>(query, db, count, signs, query_sign);
  return TwoNearestWithKernel(L2SquaredAvx2, query, db, count, dims, signs, query_sign);
}

// ---------------------------------------------------------------------------
// AVX-512. Only ever called after L2KernelAvailable(kAvx512) said yes.
#define PLACEDB_TARGET_AVX512 __attribute__((target("avx512f,avx512bw,avx512vl")))
#define PLACEDB_INLINE_AVX512 PLACEDB_TARGET_AVX512 __attribute__((always_inline)) inline

// One distance with zmm registers and a masked tail (a single distance is
// latency bound: about as fast as the AVX2 code; the gain of the AVX-512
// kernel is in TwoNearestAvx512Fixed).
PLACEDB_TARGET_AVX512 float L2SquaredAvx512(const float* a, const float* b, int n) {
  __m512 acc0 = _mm512_setzero_ps();
  __m512 acc1 = _mm512_setzero_ps();
  int i = 0;
  for (; i + 32 <= n; i += 32) {
    const __m512 d0 = _mm512_sub_ps(_mm512_loadu_ps(a + i), _mm512_loadu_ps(b + i));
    const __m512 d1 = _mm512_sub_ps(_mm512_loadu_ps(a + i + 16), _mm512_loadu_ps(b + i + 16));
    acc0 = _mm512_fmadd_ps(d0, d0, acc0);
    acc1 = _mm512_fmadd_ps(d1, d1, acc1);
  }
  for (; i < n; i += 16) {
    // The last 1..16 floats with masked loads (nothing past n is read).
    const int rest = n - i < 16 ? n - i : 16;
    const __mmask16 m = static_cast<__mmask16>((1u << rest) - 1);
    const __m512 d =
        _mm512_sub_ps(_mm512_maskz_loadu_ps(m, a + i), _mm512_maskz_loadu_ps(m, b + i));
    acc0 = _mm512_fmadd_ps(d, d, acc0);
  }
  const float sum = _mm512_reduce_add_ps(_mm512_add_ps(acc0, acc1));
  // Explicit, not left to the compiler (GCC inserts it only from -O2 on).
  _mm256_zeroupper();
  return sum;
}

// Squared distance of one row to the query held in registers, as 16 partial
// sums (one zmm).
template <int kDims>
PLACEDB_INLINE_AVX512 __m512 RowPartials(const __m512 (&q)[kDims / 16], const float* row) {
  constexpr int kBlocks = kDims / 16;
  __m512 d = _mm512_sub_ps(q[0], _mm512_loadu_ps(row));
  __m512 acc0 = _mm512_mul_ps(d, d);
  if (kBlocks >= 8) {
    // Two chains for long rows.
    d = _mm512_sub_ps(q[1], _mm512_loadu_ps(row + 16));
    __m512 acc1 = _mm512_mul_ps(d, d);
    for (int b = 2; b < kBlocks; b += 2) {
      const __m512 d0 = _mm512_sub_ps(q[b], _mm512_loadu_ps(row + 16 * b));
      const __m512 d1 = _mm512_sub_ps(q[b + 1], _mm512_loadu_ps(row + 16 * b + 16));
      acc0 = _mm512_fmadd_ps(d0, d0, acc0);
      acc1 = _mm512_fmadd_ps(d1, d1, acc1);
    }
    return _mm512_add_ps(acc0, acc1);
  }
  for (int b = 1; b < kBlocks; ++b) {
    d = _mm512_sub_ps(q[b], _mm512_loadu_ps(row + 16 * b));
    acc0 = _mm512_fmadd_ps(d, d, acc0);
  }
  return acc0;
}

// The squared distances of 16 rows (row(r) for r = 0..15) to the query, lane
// r = row r. Every lane sums its partials in the same order, so equal rows
// give bitwise equal distances wherever they are.
template <int kDims, typename RowOf>
PLACEDB_INLINE_AVX512 __m512 Distances16(const __m512 (&q)[kDims / 16], const RowOf& row) {
  // Pairs: [a0+a2, b0+b2, a1+a3, b1+b3] in each 128-bit lane.
  __m512 t[8];
  for (int p = 0; p < 8; ++p) {
    const __m512 a = RowPartials<kDims>(q, row(2 * p));
    const __m512 b = RowPartials<kDims>(q, row(2 * p + 1));
    t[p] = _mm512_add_ps(_mm512_unpacklo_ps(a, b), _mm512_unpackhi_ps(a, b));
  }
  // Fours: [r0 r1 r2 r3] per 128-bit lane (lane partials).
  __m512 u[4];
  for (int p = 0; p < 4; ++p) {
    const __m512d a = _mm512_castps_pd(t[2 * p]);
    const __m512d b = _mm512_castps_pd(t[2 * p + 1]);
    u[p] = _mm512_add_ps(_mm512_castpd_ps(_mm512_unpacklo_pd(a, b)),
                         _mm512_castpd_ps(_mm512_unpackhi_pd(a, b)));
  }
  // 128-bit lanes: (0+1, 2+3) twice, ending in row order.
  __m512 v[2];
  for (int p = 0; p < 2; ++p) {
    v[p] = _mm512_add_ps(_mm512_shuffle_f32x4(u[2 * p], u[2 * p + 1], _MM_SHUFFLE(2, 0, 2, 0)),
                         _mm512_shuffle_f32x4(u[2 * p], u[2 * p + 1], _MM_SHUFFLE(3, 1, 3, 1)));
  }
  return _mm512_add_ps(_mm512_shuffle_f32x4(v[0], v[1], _MM_SHUFFLE(2, 0, 2, 0)),
                       _mm512_shuffle_f32x4(v[0], v[1], _MM_SHUFFLE(3, 1, 3, 1)));
}

// Per lane: best, second and the index of the best among the rows that lane
// saw, which arrive in increasing index order (strict < keeps the lower).
struct LaneBest {
  __m512 best, second;
  __m512i best_index;
};

PLACEDB_INLINE_AVX512 void Track(LaneBest& s, __m512 d, __m512i index) {
  // Operand order keeps a NaN distance out (vminps/vmaxps return the second
  // operand when one is NaN), like the scalar Update.
  const __mmask16 lt = _mm512_cmp_ps_mask(d, s.best, _CMP_LT_OQ);
  s.second = _mm512_min_ps(_mm512_max_ps(s.best, d), s.second);
  s.best = _mm512_min_ps(d, s.best);
  s.best_index = _mm512_mask_mov_epi32(s.best_index, lt, index);
}

// Across lanes: the smallest best, at the lowest index among the lanes that
// have it; second = min(second of that lane, best of every other lane).
PLACEDB_INLINE_AVX512 TwoNearestL2Result Finish(const LaneBest& s) {
  TwoNearestL2Result out;
  const float b = _mm512_reduce_min_ps(s.best);
  if (!(b < std::numeric_limits<float>::infinity())) return out;  // no candidate
  const __mmask16 at = _mm512_cmp_ps_mask(s.best, _mm512_set1_ps(b), _CMP_EQ_OQ);
  const int bi = _mm512_mask_reduce_min_epi32(at, s.best_index);
  const __mmask16 win = _mm512_mask_cmpeq_epi32_mask(at, s.best_index, _mm512_set1_epi32(bi));
  out.best = b;
  out.second = _mm512_reduce_min_ps(_mm512_mask_mov_ps(s.best, win, s.second));
  out.best_index = bi;
  return out;
}

// The rows listed in rows[0..lanes) (1..16 of them, increasing).
template <int kDims>
PLACEDB_INLINE_AVX512 void ScanGathered(const __m512 (&q)[kDims / 16], const float* db,
                                        const int32_t* rows, int lanes, LaneBest& s) {
  const __m512i index = _mm512_loadu_si512(rows);
  __m512 d = Distances16<kDims>(q, [rows, db, lanes](int r) {
    return db + static_cast<size_t>(rows[r < lanes ? r : 0]) * kDims;
  });
  if (lanes < 16) {
    d = _mm512_mask_mov_ps(_mm512_set1_ps(std::numeric_limits<float>::infinity()),
                           static_cast<__mmask16>((1u << lanes) - 1), d);
  }
  Track(s, d, index);
}

template <int kDims>
PLACEDB_TARGET_AVX512 TwoNearestL2Result TwoNearestAvx512Fixed(const float* query, const float* db,
                                                               int count, const int8_t* signs,
                                                               int8_t query_sign) {
  constexpr int kBlocks = kDims / 16;
  __m512 q[kBlocks];
  for (int b = 0; b < kBlocks; ++b) q[b] = _mm512_loadu_ps(query + 16 * b);
  const __m512 inf = _mm512_set1_ps(std::numeric_limits<float>::infinity());
  const __m512i iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  LaneBest s{inf, inf, _mm512_set1_epi32(-1)};
  if (signs == nullptr) {
    int j = 0;
    for (; j + 16 <= count; j += 16) {
      const float* base = db + static_cast<size_t>(j) * kDims;
      const __m512 d = Distances16<kDims>(q, [base](int r) { return base + r * kDims; });
      Track(s, d, _mm512_add_epi32(iota, _mm512_set1_epi32(j)));
    }
    if (j < count) {
      // 1..15 rows left: the missing lanes read the last row again and are
      // set to +infinity (never < best; max(best, inf) leaves second).
      const int rest = count - j;
      const float* base = db + static_cast<size_t>(j) * kDims;
      __m512 d = Distances16<kDims>(
          q, [base, rest](int r) { return base + (r < rest ? r : rest - 1) * kDims; });
      d = _mm512_mask_mov_ps(inf, static_cast<__mmask16>((1u << rest) - 1), d);
      Track(s, d, _mm512_add_epi32(iota, _mm512_set1_epi32(j)));
    }
    const TwoNearestL2Result out = Finish(s);
    _mm256_zeroupper();
    return out;
  }
  // With signs: the indices of the rows of the query's sign are listed (in
  // increasing order) for a chunk of rows, then scanned 16 at a time like
  // contiguous rows; fewer than 16 left over wait for the next chunk.
  constexpr int kChunk = 256;
  alignas(64) int32_t rows[kChunk + 32];
  int pending = 0;
  const __m512i want = _mm512_set1_epi8(query_sign);
  for (int chunk = 0; chunk < count; chunk += kChunk) {
    const int end = count - chunk < kChunk ? count : chunk + kChunk;
    for (int j = chunk; j < end; j += 64) {
      // 64 signs at a time, their rows listed 16 at a time.
      const int n = end - j < 64 ? end - j : 64;
      const __mmask64 in = n == 64 ? ~__mmask64{0} : (__mmask64{1} << n) - 1;
      const __mmask64 same =
          _mm512_mask_cmpeq_epi8_mask(in, _mm512_maskz_loadu_epi8(in, signs + j), want);
      for (int t = 0; t < 4; ++t) {
        const __mmask16 part = static_cast<__mmask16>(same >> (16 * t));
        const __m512i ids = _mm512_maskz_compress_epi32(
            part, _mm512_add_epi32(iota, _mm512_set1_epi32(j + 16 * t)));
        _mm512_storeu_si512(rows + pending, ids);  // pending + 16 <= kChunk + 31
        pending += __builtin_popcount(static_cast<unsigned>(part));
      }
    }
    int g = 0;
    for (; g + 16 <= pending; g += 16) ScanGathered<kDims>(q, db, rows + g, 16, s);
    for (int t = g; t < pending; ++t) rows[t - g] = rows[t];
    pending -= g;
  }
  if (pending > 0) ScanGathered<kDims>(q, db, rows, pending, s);
  const TwoNearestL2Result out = Finish(s);
  _mm256_zeroupper();
  return out;
}

TwoNearestL2Result TwoNearestAvx512(const float* query, const float* db, int count, int dims,
                                    const int8_t* signs, int8_t query_sign) {
  if (count <= 0) return TwoNearestL2Result{};
  if (dims == 64) return TwoNearestAvx512Fixed<64>(query, db, count, signs, query_sign);
  if (dims == 128) return TwoNearestAvx512Fixed<128>(query, db, count, signs, query_sign);
  return TwoNearestWithKernel(L2SquaredAvx512, query, db, count, dims, signs, query_sign);
}
#undef PLACEDB_INLINE_AVX512
#undef PLACEDB_TARGET_AVX512

#endif  // PLACEDB_L2_X86

using Kernel = L2Kernel;

bool CpuRuns(Kernel kernel) {
#if defined(PLACEDB_L2_X86)
  __builtin_cpu_init();
  switch (kernel) {
    case Kernel::kReference:
      return true;
    case Kernel::kSse2:
      return __builtin_cpu_supports("sse2");
    case Kernel::kAvx2:
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    case Kernel::kAvx512:
      // __builtin_cpu_supports also checks that the OS saves the zmm state.
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
             __builtin_cpu_supports("avx512vl");
  }
  return false;
#else
  return kernel == Kernel::kReference;
#endif
}

// What the CPU runs, computed once.
struct Support {
  bool runs[kNumL2Kernels];
  Kernel best = Kernel::kReference;
  Support() {
    for (int k = 0; k < kNumL2Kernels; ++k) {
      runs[k] = CpuRuns(static_cast<Kernel>(k));
      if (runs[k]) best = static_cast<Kernel>(k);  // kernels are listed slowest first
    }
  }
};

const Support& GetSupport() {
  static const Support support;
  return support;
}

float Distance(Kernel kernel, const float* a, const float* b, int n) {
  switch (kernel) {
#if defined(PLACEDB_L2_X86)
    case Kernel::kAvx512:
      return L2SquaredAvx512(a, b, n);
    case Kernel::kAvx2:
      return L2SquaredAvx2(a, b, n);
    case Kernel::kSse2:
      return L2SquaredSse2(a, b, n);
#endif
    default:
      return L2SquaredReference(a, b, n);
  }
}

TwoNearestL2Result Run(Kernel kernel, const float* query, const float* db, int count, int dims,
                       const int8_t* signs, int8_t query_sign) {
  switch (kernel) {
#if defined(PLACEDB_L2_X86)
    case Kernel::kAvx512:
      return TwoNearestAvx512(query, db, count, dims, signs, query_sign);
    case Kernel::kAvx2:
      return TwoNearestAvx2(query, db, count, dims, signs, query_sign);
    case Kernel::kSse2:
      return TwoNearestWithKernel(L2SquaredSse2, query, db, count, dims, signs, query_sign);
#endif
    default:
      return TwoNearestL2Reference(query, db, count, dims, signs, query_sign);
  }
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

float L2Squared(const float* a, const float* b, int n) {
  return Distance(ActiveL2Kernel(), a, b, n);
}

TwoNearestL2Result TwoNearestL2Reference(const float* query, const float* db, int count, int dims,
                                         const int8_t* signs, int8_t query_sign) {
  return TwoNearestWithKernel(L2SquaredReference, query, db, count, dims, signs, query_sign);
}

TwoNearestL2Result TwoNearestL2(const float* query, const float* db, int count, int dims,
                                const int8_t* signs, int8_t query_sign) {
  return Run(ActiveL2Kernel(), query, db, count, dims, signs, query_sign);
}

bool L2KernelAvailable(L2Kernel kernel) {
  const int k = static_cast<int>(kernel);
  return k >= 0 && k < kNumL2Kernels && GetSupport().runs[k];
}

float L2SquaredWith(L2Kernel kernel, const float* a, const float* b, int n) {
  if (!L2KernelAvailable(kernel)) kernel = Kernel::kReference;
  return Distance(kernel, a, b, n);
}

TwoNearestL2Result TwoNearestL2With(L2Kernel kernel, const float* query, const float* db, int count,
                                    int dims, const int8_t* signs, int8_t query_sign) {
  if (!L2KernelAvailable(kernel)) kernel = Kernel::kReference;
  return Run(kernel, query, db, count, dims, signs, query_sign);
}

L2Kernel BestL2Kernel() { return GetSupport().best; }

L2Kernel ChooseL2Kernel(const char* requested) {
  const char* (*name)(L2Kernel) = L2KernelName;
  return internal::ChooseKernel(requested, "PLACEDB_L2_KERNEL", kNumL2Kernels, BestL2Kernel(), name,
                                L2KernelAvailable);
}

L2Kernel ActiveL2Kernel() {
  static const Kernel kernel = ChooseL2Kernel(std::getenv("PLACEDB_L2_KERNEL"));
  return kernel;
}

const char* L2KernelName(L2Kernel kernel) {
  switch (kernel) {
    case Kernel::kReference:
      return "reference";
    case Kernel::kSse2:
      return "sse2";
    case Kernel::kAvx2:
      return "avx2";
    case Kernel::kAvx512:
      return "avx512";
  }
  return "unknown";
}

std::optional<L2Kernel> L2KernelFromName(const char* name) {
  const char* (*kernel_name)(L2Kernel) = L2KernelName;
  return internal::KernelFromName(name, kNumL2Kernels, kernel_name);
}

const char* L2KernelName() { return L2KernelName(ActiveL2Kernel()); }


}  // namespace placedb
