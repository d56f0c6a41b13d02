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
__attribute__((target("avx2"))) inline int32_t HorizontalSum(__m256i v) {
  const __m128i s = _mm_add_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256(v, 1));
  const __m128i t = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0x4e));
  return _mm_cvtsi128_si32(_mm_add_epi32(t, _mm_shuffle_epi32(t, 0xb1)));
}

// 32 values at a time: maddubs(|q|, sign(r, q)) sums pairs of q r into
// int16 (at most 2 * 127 * 127: no saturation for values in [-127, 127]),
// madd with ones widens them to int32; the row's squares the same way with
// |r|. Two rows per step share the query's loads; the tail (dims % 32) is
// scalar.
__attribute__((target("avx2"))) inline void Block(__m256i qa, __m256i q, const int8_t* r,
                                                  __m256i ones, __m256i* dot, __m256i* rr) {
  const __m256i v = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(r));
  const __m256i av = _mm256_abs_epi8(v);
  const __m256i qv = _mm256_maddubs_epi16(qa, _mm256_sign_epi8(v, q));
  const __m256i vv = _mm256_maddubs_epi16(av, av);
  *dot = _mm256_add_epi32(*dot, _mm256_madd_epi16(qv, ones));
  *rr = _mm256_add_epi32(*rr, _mm256_madd_epi16(vv, ones));
}

__attribute__((target("avx2"))) void SimilaritiesAvx2(const int8_t* query, const int8_t* rows,
                                                      size_t count, int dims, float* out) {
  int64_t qq = 0;
  for (int d = 0; d < dims; ++d) qq += int32_t{query[d]} * query[d];
  const int blocks = dims / 32;
  const __m256i ones = _mm256_set1_epi16(1);
  const size_t stride = static_cast<size_t>(dims);
  auto tail = [&](const int8_t* r, int32_t* d32, int32_t* r32) {
    for (int d = 32 * blocks; d < dims; ++d) {
      *d32 += int32_t{query[d]} * r[d];
      *r32 += int32_t{r[d]} * r[d];
    }
  };
  size_t i = 0;
  for (; i + 2 <= count; i += 2) {
    const int8_t* r0 = rows + i * stride;
    const int8_t* r1 = r0 + stride;
    __m256i dot0 = _mm256_setzero_si256(), rr0 = _mm256_setzero_si256();
    __m256i dot1 = _mm256_setzero_si256(), rr1 = _mm256_setzero_si256();
    for (int b = 0; b < blocks; ++b) {
      const __m256i q = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(query + 32 * b));
      const __m256i qa = _mm256_abs_epi8(q);
      Block(qa, q, r0 + 32 * b, ones, &dot0, &rr0);
      Block(qa, q, r1 + 32 * b, ones, &dot1, &rr1);
    }
    int32_t d0 = HorizontalSum(dot0), n0 = HorizontalSum(rr0);
    int32_t d1 = HorizontalSum(dot1), n1 = HorizontalSum(rr1);
    tail(r0, &d0, &n0);
    tail(r1, &d1, &n1);
    out[i] = Cosine(d0, qq, n0);
    out[i + 1] = Cosine(d1, qq, n1);
  }
  for (; i < count; ++i) {
    const int8_t* r = rows + i * stride;
    __m256i dot = _mm256_setzero_si256(), rr = _mm256_setzero_si256();
    for (int b = 0; b < blocks; ++b) {
      const __m256i q = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(query + 32 * b));
      Block(_mm256_abs_epi8(q), q, r + 32 * b, ones, &dot, &rr);
    }
    int32_t d32 = HorizontalSum(dot), r32 = HorizontalSum(rr);
    tail(r, &d32, &r32);
    out[i] = Cosine(d32, qq, r32);
  }
  _mm256_zeroupper();
}

bool CpuRuns(WholeImageKernel kernel) {
  __builtin_cpu_init();
  return kernel == WholeImageKernel::kReference || __builtin_cpu_supports("avx2");
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
  return kernel == WholeImageKernel::kAvx2 ? "avx2" : "reference";
}

bool WholeImageKernelAvailable(WholeImageKernel kernel) {
  static const bool avx2 = CpuRuns(WholeImageKernel::kAvx2);
  return kernel == WholeImageKernel::kReference || (kernel == WholeImageKernel::kAvx2 && avx2);
}

WholeImageKernel ActiveWholeImageKernel() {
  static const WholeImageKernel active = WholeImageKernelAvailable(WholeImageKernel::kAvx2)
                                             ? WholeImageKernel::kAvx2
                                             : WholeImageKernel::kReference;
  return active;
}

void WholeImageSimilaritiesWith(WholeImageKernel kernel, const int8_t* query, const int8_t* rows,
                                size_t count, int dims, float* out) {
  if (dims < 1 || dims > (1 << 16)) PLACEDB_THROW_INVALID("whole-image rows of ", dims, " values");
  if (!WholeImageKernelAvailable(kernel)) {
    PLACEDB_THROW_INVALID("whole-image kernel ", WholeImageKernelName(kernel),
                          " is not available on this CPU");
  }
#if PLACEDB_X86
  if (kernel == WholeImageKernel::kAvx2) return SimilaritiesAvx2(query, rows, count, dims, out);
#endif
  SimilaritiesReference(query, rows, count, dims, out);
}

void WholeImageSimilarities(const int8_t* query, const int8_t* rows, size_t count, int dims,
                            float* out) {
  WholeImageSimilaritiesWith(ActiveWholeImageKernel(), query, rows, count, dims, out);
}

}  // namespace placedb
