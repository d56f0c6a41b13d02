#include "placedb/feature/whole_image.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "placedb/image/chromaticity.h"
#include "placedb/util/check.h"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define PLACEDB_X86 1
#endif

namespace placedb {

cv::Mat ComputeWholeImageDescriptor(const cv::Mat& image, const WholeImageOptions& o) {
  PLACEDB_CHECK_OPTIONS(o);
  if (image.empty()) PLACEDB_THROW_INVALID("the whole-image descriptor of an empty image");
  const cv::Mat gray = ToGray(image);  // InvalidArgument unless 8-bit, 1, 3 or 4 channels
  cv::Mat gray_f;
  gray.convertTo(gray_f, CV_32F);
  cv::Mat thumb;
  cv::resize(gray_f, thumb, cv::Size(o.width, o.height), 0, 0, cv::INTER_AREA);
  cv::Mat out(1, o.width * o.height, CV_8S);
  int8_t* row = out.ptr<int8_t>(0);
  for (int ty = 0; ty < o.height; ty += o.patch) {
    for (int tx = 0; tx < o.width; tx += o.patch) {
      const int y1 = std::min(ty + o.patch, o.height), x1 = std::min(tx + o.patch, o.width);
      double sum = 0.0;
      for (int y = ty; y < y1; ++y) {
        const float* p = thumb.ptr<float>(y);
        for (int x = tx; x < x1; ++x) sum += p[x];
      }
      const double n = static_cast<double>((y1 - ty) * (x1 - tx));
      const double mean = sum / n;
      double squares = 0.0;
      for (int y = ty; y < y1; ++y) {
        const float* p = thumb.ptr<float>(y);
        for (int x = tx; x < x1; ++x) squares += (p[x] - mean) * (p[x] - mean);
      }
      const double sd = std::sqrt(squares / n);
      for (int y = ty; y < y1; ++y) {
        const float* p = thumb.ptr<float>(y);
        for (int x = tx; x < x1; ++x) {
          int8_t v = 0;
          if (sd >= 1e-6) {
            const double z = std::clamp((p[x] - mean) / sd, -4.0, 4.0);
            v = static_cast<int8_t>(std::lround(z * 31.75));
          }
          row[y * o.width + x] = v;
        }
      }
    }
  }
  return out;
}

namespace {

// The cosine from the sums (0 when a norm is 0), in double so that every
// kernel rounds the same integers the same way.
inline float Cosine(int64_t dot, int64_t qq, int64_t rr) {
  if (qq == 0 || rr == 0) return 0.0f;
  const double c = static_cast<double>(dot) /
                   std::sqrt(static_cast<double>(qq) * static_cast<double>(rr));
  return static_cast<float>(std::clamp(c, -1.0, 1.0));
}

void SimilaritiesReference(const int8_t* query, const int8_t* rows, size_t count, int dims,
                           float* out) {
  int64_t qq = 0;
  for (int d = 0; d < dims; ++d) qq += int32_t{query[d]} * query[d];
  for (size_t i = 0; i < count; ++i) {
    const int8_t* r = rows + i * static_cast<size_t>(dims);
    int32_t dot = 0, rr = 0;
    for (int d = 0; d < dims; ++d) {
      dot += int32_t{query[d]} * r[d];
      rr += int32_t{r[d]} * r[d];
    }
    out[i] = Cosine(dot, qq, rr);
  }
}

#if PLACEDB_X86
#define PLACEDB_AVX2 __attribute__((target("avx2")))

PLACEDB_AVX2 inline int32_t HorizontalSum(__m256i v) {
  const __m128i s = _mm_add_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
  const __m128i t = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0x4e));
  return _mm_cvtsi128_si32(_mm_add_epi32(t, _mm_shuffle_epi32(t, 0xb1)));
}

// The sums of four rows' accumulators (8 int32 each), as 4 int32.
PLACEDB_AVX2 inline __m128i HorizontalSum4(__m256i a, __m256i b, __m256i c, __m256i d) {
  const __m256i t = _mm256_hadd_epi32(_mm256_hadd_epi32(a, b), _mm256_hadd_epi32(c, d));
  return _mm_add_epi32(_mm256_castsi256_si128(t), _mm256_extracti128_si256(t, 1));
}

// 32 values of one row: maddubs(|q|, sign(r, q)) sums pairs of q r into
// int16 (at most 2 * 127 * 127: no saturation for values in [-127, 127]),
// madd with ones widens them to int32; the row's squares the same way
// with |r|.
PLACEDB_AVX2 inline void BlockAvx2(__m256i qa, __m256i q, const int8_t* r, __m256i* dot,
                                   __m256i* rr) {
  const __m256i ones = _mm256_set1_epi16(1);
  const __m256i v = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(r));
  const __m256i av = _mm256_abs_epi8(v);
  const __m256i qv = _mm256_maddubs_epi16(qa, _mm256_sign_epi8(v, q));
  const __m256i vv = _mm256_maddubs_epi16(av, av);
  *dot = _mm256_add_epi32(*dot, _mm256_madd_epi16(qv, ones));
  *rr = _mm256_add_epi32(*rr, _mm256_madd_epi16(vv, ones));
}

// The same with AVX-VNNI: vpdpbusd multiplies unsigned by signed bytes and
// adds each four products into an int32 lane, in one instruction.
#define PLACEDB_AVXVNNI __attribute__((target("avx2,avxvnni")))
PLACEDB_AVXVNNI inline void BlockAvxVnni(__m256i qa, __m256i q, const int8_t* r, __m256i* dot,
                                         __m256i* rr) {
  const __m256i v = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(r));
  const __m256i av = _mm256_abs_epi8(v);
  *dot = _mm256_dpbusd_avx_epi32(*dot, qa, _mm256_sign_epi8(v, q));
  *rr = _mm256_dpbusd_avx_epi32(*rr, av, av);
}

// Four cosines at once, each computed as Cosine computes it (the same
// double operations, so the same floats).
PLACEDB_AVX2 inline void Cosine4(__m128i dot, int64_t qq, __m128i rr, float* out) {
  const __m256d d = _mm256_cvtepi32_pd(dot), r = _mm256_cvtepi32_pd(rr);
  const __m256d c =
      _mm256_div_pd(d, _mm256_sqrt_pd(_mm256_mul_pd(_mm256_set1_pd(static_cast<double>(qq)), r)));
  const __m256d clamped =
      _mm256_min_pd(_mm256_max_pd(c, _mm256_set1_pd(-1.0)), _mm256_set1_pd(1.0));
  const __m256d none = qq == 0 ? _mm256_castsi256_pd(_mm256_set1_epi64x(-1))
                               : _mm256_cmp_pd(r, _mm256_setzero_pd(), _CMP_EQ_OQ);
  _mm_storeu_ps(out, _mm256_cvtpd_ps(_mm256_andnot_pd(none, clamped)));
}

// The rows' pass, for a Block of 32 values: four rows a step (they share
// the query's loads, their sums and cosines are taken together, and the
// group after next is prefetched), the rest one by one; the tail (dims %
// 32) is scalar. Stamped out once per target (a function's target cannot
// follow a template parameter).
#define PLACEDB_WHOLE_IMAGE_PASS(TARGET, NAME, BLOCK)                                          \
  TARGET void NAME(const int8_t* query, const int8_t* rows, size_t count, int dims,           \
                   float* out) {                                                              \
    int64_t qq = 0;                                                                           \
    for (int d = 0; d < dims; ++d) qq += int32_t{query[d]} * query[d];                        \
    const int blocks = dims / 32;                                                             \
    const size_t stride = static_cast<size_t>(dims);                                          \
    const auto tail = [&](const int8_t* r, int32_t* dot, int32_t* rr) {                       \
      for (int d = 32 * blocks; d < dims; ++d) {                                              \
        *dot += int32_t{query[d]} * r[d];                                                     \
        *rr += int32_t{r[d]} * r[d];                                                          \
      }                                                                                       \
    };                                                                                        \
    size_t i = 0;                                                                             \
    for (; i + 4 <= count; i += 4) {                                                          \
      const int8_t* r = rows + i * stride;                                                    \
      const char* next = reinterpret_cast<const char*>(r + 4 * stride);                       \
      __m256i d0 = _mm256_setzero_si256(), d1 = d0, d2 = d0, d3 = d0;                         \
      __m256i n0 = d0, n1 = d0, n2 = d0, n3 = d0;                                             \
      for (int b = 0; b < blocks; ++b) {                                                      \
        if ((b & 1) == 0 && i + 8 <= count) {                                                 \
          for (size_t j = 0; j < 4; ++j) _mm_prefetch(next + j * stride + 32 * b, _MM_HINT_T0); \
        }                                                                                     \
        const __m256i q = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(query + 32 * b)); \
        const __m256i qa = _mm256_abs_epi8(q);                                                \
        BLOCK(qa, q, r + 32 * b, &d0, &n0);                                                   \
        BLOCK(qa, q, r + stride + 32 * b, &d1, &n1);                                          \
        BLOCK(qa, q, r + 2 * stride + 32 * b, &d2, &n2);                                      \
        BLOCK(qa, q, r + 3 * stride + 32 * b, &d3, &n3);                                      \
      }                                                                                       \
      __m128i dots = HorizontalSum4(d0, d1, d2, d3), norms = HorizontalSum4(n0, n1, n2, n3);  \
      if (32 * blocks < dims) {                                                               \
        alignas(16) int32_t dt[4], nt[4];                                                     \
        _mm_store_si128(reinterpret_cast<__m128i*>(dt), dots);                                \
        _mm_store_si128(reinterpret_cast<__m128i*>(nt), norms);                               \
        for (int j = 0; j < 4; ++j) tail(r + j * stride, &dt[j], &nt[j]);                     \
        dots = _mm_load_si128(reinterpret_cast<const __m128i*>(dt));                          \
        norms = _mm_load_si128(reinterpret_cast<const __m128i*>(nt));                         \
      }                                                                                       \
      Cosine4(dots, qq, norms, out + i);                                                      \
    }                                                                                         \
    for (; i < count; ++i) {                                                                  \
      const int8_t* r = rows + i * stride;                                                    \
      __m256i dot = _mm256_setzero_si256(), rr = dot;                                         \
      for (int b = 0; b < blocks; ++b) {                                                      \
        const __m256i q = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(query + 32 * b)); \
        BLOCK(_mm256_abs_epi8(q), q, r + 32 * b, &dot, &rr);                                  \
      }                                                                                       \
      int32_t d32 = HorizontalSum(dot), r32 = HorizontalSum(rr);                              \
      tail(r, &d32, &r32);                                                                    \
      out[i] = Cosine(d32, qq, r32);                                                          \
    }                                                                                         \
    _mm256_zeroupper();                                                                       \
  }

PLACEDB_WHOLE_IMAGE_PASS(PLACEDB_AVX2, SimilaritiesAvx2, BlockAvx2)
PLACEDB_WHOLE_IMAGE_PASS(PLACEDB_AVXVNNI, SimilaritiesAvxVnni, BlockAvxVnni)
#undef PLACEDB_WHOLE_IMAGE_PASS
#undef PLACEDB_AVXVNNI
#undef PLACEDB_AVX2

bool CpuRuns(WholeImageKernel kernel) {
  __builtin_cpu_init();
  switch (kernel) {
    case WholeImageKernel::kReference:
      return true;
    case WholeImageKernel::kAvx2:
      return __builtin_cpu_supports("avx2");
    case WholeImageKernel::kAvxVnni:
      // __builtin_cpu_supports knows "avxvnni" from GCC 11 on.
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("avxvnni");
  }
  return false;
}
#else
bool CpuRuns(WholeImageKernel kernel) { return kernel == WholeImageKernel::kReference; }
#endif

}  // namespace

double WholeImageSimilarity(const int8_t* a, const int8_t* b, int dims) {
  int64_t dot = 0, aa = 0, bb = 0;
  for (int d = 0; d < dims; ++d) {
    dot += int32_t{a[d]} * b[d];
    aa += int32_t{a[d]} * a[d];
    bb += int32_t{b[d]} * b[d];
  }
  if (aa == 0 || bb == 0) return 0.0;
  return std::clamp(static_cast<double>(dot) /
                        std::sqrt(static_cast<double>(aa) * static_cast<double>(bb)),
                    -1.0, 1.0);
}

const char* WholeImageKernelName(WholeImageKernel kernel) {
  switch (kernel) {
    case WholeImageKernel::kAvx2:
      return "avx2";
    case WholeImageKernel::kAvxVnni:
      return "avxvnni";
    default:
      return "reference";
  }
}

namespace {
// What the CPU runs, found once; kernels are listed slowest first.
struct WholeImageSupport {
  bool runs[kNumWholeImageKernels] = {};
  WholeImageKernel best = WholeImageKernel::kReference;
  WholeImageSupport() {
    for (int k = 0; k < kNumWholeImageKernels; ++k) {
      runs[k] = CpuRuns(static_cast<WholeImageKernel>(k));
      if (runs[k]) best = static_cast<WholeImageKernel>(k);
    }
  }
};
const WholeImageSupport& Support() {
  static const WholeImageSupport support;
  return support;
}
}  // namespace

bool WholeImageKernelAvailable(WholeImageKernel kernel) {
  const int k = static_cast<int>(kernel);
  return k >= 0 && k < kNumWholeImageKernels && Support().runs[k];
}

WholeImageKernel ActiveWholeImageKernel() { return Support().best; }

void WholeImageSimilaritiesWith(WholeImageKernel kernel, const int8_t* query, const int8_t* rows,
                                size_t count, int dims, float* out) {
  if (dims < 1 || dims > (1 << 16)) PLACEDB_THROW_INVALID("whole-image rows of ", dims, " values");
  if (!WholeImageKernelAvailable(kernel)) {
    PLACEDB_THROW_INVALID("whole-image kernel ", WholeImageKernelName(kernel),
                          " is not available on this CPU");
  }
#if PLACEDB_X86
  if (kernel == WholeImageKernel::kAvx2) return SimilaritiesAvx2(query, rows, count, dims, out);
  if (kernel == WholeImageKernel::kAvxVnni)
    return SimilaritiesAvxVnni(query, rows, count, dims, out);
#endif
  SimilaritiesReference(query, rows, count, dims, out);
}

void WholeImageSimilarities(const int8_t* query, const int8_t* rows, size_t count, int dims,
                            float* out) {
  WholeImageSimilaritiesWith(ActiveWholeImageKernel(), query, rows, count, dims, out);
}

}  // namespace placedb
