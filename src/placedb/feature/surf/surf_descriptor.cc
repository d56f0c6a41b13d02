#include "placedb/feature/surf/surf_descriptor.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "placedb/feature/surf/surf_simd.h"

#if defined(PLACEDB_SURF_X86)
#include <immintrin.h>
#endif

// Orientation and descriptor are written once (OrientationBody,
// DescriptorBody) and compiled twice, plain and AVX2+FMA; see surf_simd.h.
// Every operation is the same in both copies (the AVX2 Haar kernel
// reproduces HaarSubPixel's arithmetic lane by lane), so their results are
// bit-identical.

namespace placedb {
namespace surf_internal {
namespace {

constexpr float kPi = 3.14159265358979f;
constexpr int kOriRadius = 6;        // Orientation samples within 6s.
constexpr float kOriSigma = 2.5f;    // Orientation Gaussian, in units of s.
constexpr int kOriBins = 120;        // Angular bins of 3 degrees.
constexpr int kOriWindowBins = 20;   // Sliding window: 60 degrees.
constexpr int kMaxOriSamples = 112;  // 109 samples, padded to 8.
constexpr int kPatch = 20;           // Descriptor window: 20 x 20 samples.
constexpr int kSub = 5;              // Samples per sub-region side.
constexpr int kNumSub = 16;          // 4 x 4 sub-regions.
constexpr int kNumSamples = kPatch * kPatch;
constexpr float kDescSigma = 3.3f;  // Descriptor Gaussian, in units of s.

// Round half to even (std::lrint in the default rounding mode) without the
// libm call that baseline x86-64 makes for lrint.
PLACEDB_SURF_INLINE int Round(float v) {
#if defined(PLACEDB_SURF_X86)
  return _mm_cvtss_si32(_mm_set_ss(v));
#else
  return static_cast<int>(std::lrint(v));
#endif
}

// floor for |v| < 2^31 (sub-pixel sample positions inside the image).
PLACEDB_SURF_INLINE int FloorToInt(float v) {
  const int t = static_cast<int>(v);
  return t - (v < static_cast<float>(t) ? 1 : 0);
}

// Offsets of the integral reads of a Haar pair of side h (even).
struct HaarOffsets {
  int h = 2;
  int half = 1;
  int stride = 1;
  ptrdiff_t row_half = 0;
  ptrdiff_t row_full = 0;
  HaarOffsets(int side, int table_stride)
      : h(side),
        half(side / 2),
        stride(table_stride),
        row_half(static_cast<ptrdiff_t>(side / 2) * table_stride),
        row_full(static_cast<ptrdiff_t>(side) * table_stride) {}
};

// Haar responses of the h x h box whose top-left table entry is p:
// dx = right half - left half, dy = bottom half - top half (pixel sums).
PLACEDB_SURF_INLINE void Haar(const uint32_t* p, const HaarOffsets& o, float* dx, float* dy) {
  const uint32_t a00 = p[0], a01 = p[o.half], a02 = p[o.h];
  const uint32_t* q = p + o.row_half;
  const uint32_t a10 = q[0], a12 = q[o.h];
  const uint32_t* z = p + o.row_full;
  const uint32_t a20 = z[0], a21 = z[o.half], a22 = z[o.h];
  // dx uses rows 0 and 2 only, dy columns 0 and 2 only.
  const uint32_t gx = (a22 + a20 - 2u * a21) - (a02 + a00 - 2u * a01);
  const uint32_t gy = (a22 + a02 - 2u * a12) - (a20 + a00 - 2u * a10);
  *dx = static_cast<float>(static_cast<int32_t>(gx));
  *dy = static_cast<float>(static_cast<int32_t>(gy));
}

// Haar responses of the box of side h centred at the real point (x, y)
// (pixel centres at integers), exact for the piecewise-constant image: the
// integral image is bilinear between its entries, so the responses are the
// bilinear blend of the four integer-anchored responses around the point
// (along x, then along y; HaarBatchAvx2 does the same operations).
// The box and its neighbour one pixel right/down must lie inside the image.
PLACEDB_SURF_INLINE void HaarSubPixel(const IntegralImage& ii, const HaarOffsets& o, float x,
                                      float y, float* dx, float* dy) {
  const float lift = 0.5f * static_cast<float>(o.h - 1);
  const float fx0 = x - lift;
  const float fy0 = y - lift;
  const int tx = FloorToInt(fx0);
  const int ty = FloorToInt(fy0);
  const float fx = fx0 - static_cast<float>(tx);
  const float fy = fy0 - static_cast<float>(ty);
  const uint32_t* p = ii.Row(ty) + tx;
  float x00, y00, x01, y01, x10, y10, x11, y11;
  Haar(p, o, &x00, &y00);
  Haar(p + 1, o, &x01, &y01);
  Haar(p + o.stride, o, &x10, &y10);
  Haar(p + o.stride + 1, o, &x11, &y11);
  const float gx = 1.f - fx, gy = 1.f - fy;
  const float top_x = gx * x00 + fx * x01, bot_x = gx * x10 + fx * x11;
  const float top_y = gx * y00 + fx * y01, bot_y = gx * y10 + fx * y11;
  *dx = gy * top_x + fy * bot_x;
  *dy = gy * top_y + fy * bot_y;
}

// Near the border: the box is rounded to whole pixels and moved inside the
// image (replicating the border responses); false when it cannot fit.
PLACEDB_SURF_INLINE bool HaarClamped(const IntegralImage& ii, const HaarOffsets& o, float x,
                                     float y, float* dx, float* dy) {
  const float lift = 0.5f * static_cast<float>(o.h - 1);
  const int max_x = ii.cols() - o.h;
  const int max_y = ii.rows() - o.h;
  if (max_x < 0 || max_y < 0) return false;
  const int tx = std::min(std::max(Round(x - lift), 0), max_x);
  const int ty = std::min(std::max(Round(y - lift), 0), max_y);
  Haar(ii.Row(ty) + tx, o, dx, dy);
  return true;
}

PLACEDB_SURF_INLINE void HaarBatchPlain(const IntegralImage& ii, const HaarOffsets& o,
                                        const float* xs, const float* ys, int n, float* dx,
                                        float* dy) {
  for (int i = 0; i < n; ++i) HaarSubPixel(ii, o, xs[i], ys[i], &dx[i], &dy[i]);
}

#if defined(PLACEDB_SURF_X86)
// Entries e (*lo) and e + 1 (*hi) of 8 points, e = anchor + off; base_a holds
// the anchors of points 0 1 4 5, base_b those of points 2 3 6 7, so that
// shuffle_ps of the two 4-point gathers lists the points in order.
PLACEDB_SURF_AVX2 PLACEDB_SURF_INLINE void GatherPair(const long long* table, __m128i base_a,
                                                      __m128i base_b, int off, __m256i* lo,
                                                      __m256i* hi) {
  const __m128i k = _mm_set1_epi32(off);
  const __m256 a = _mm256_castsi256_ps(_mm256_i32gather_epi64(table, _mm_add_epi32(base_a, k), 4));
  const __m256 b = _mm256_castsi256_ps(_mm256_i32gather_epi64(table, _mm_add_epi32(base_b, k), 4));
  *lo = _mm256_castps_si256(_mm256_shuffle_ps(a, b, _MM_SHUFFLE(2, 0, 2, 0)));
  *hi = _mm256_castps_si256(_mm256_shuffle_ps(a, b, _MM_SHUFFLE(3, 1, 3, 1)));
}

// Haar of 8 anchors from their 8 entries each (see Haar).
PLACEDB_SURF_AVX2 PLACEDB_SURF_INLINE void HaarFromEntries(__m256i a00, __m256i a01, __m256i a02,
                                                           __m256i a10, __m256i a12, __m256i a20,
                                                           __m256i a21, __m256i a22, __m256* rx,
                                                           __m256* ry) {
  // gx = (a22 + a20 - 2 a21) - (a02 + a00 - 2 a01), gy likewise.
  const __m256i gx =
      _mm256_sub_epi32(_mm256_sub_epi32(_mm256_add_epi32(a22, a20), _mm256_slli_epi32(a21, 1)),
                       _mm256_sub_epi32(_mm256_add_epi32(a02, a00), _mm256_slli_epi32(a01, 1)));
  const __m256i gy =
      _mm256_sub_epi32(_mm256_sub_epi32(_mm256_add_epi32(a22, a02), _mm256_slli_epi32(a12, 1)),
                       _mm256_sub_epi32(_mm256_add_epi32(a20, a00), _mm256_slli_epi32(a10, 1)));
  *rx = _mm256_cvtepi32_ps(gx);
  *ry = _mm256_cvtepi32_ps(gy);
}

// HaarSubPixel for 8 points at a time with AVX2 gathers. The four
// integer-anchored responses around a point (anchors p, p + 1, p + stride,
// p + stride + 1) read 32 table entries that come in 16 horizontally
// adjacent pairs (e, e + 1): each pair is gathered as one 64-bit element,
// 4 points per gather, which halves the gathered elements. The table is
// addressed with 32-bit indices: callers check that it has < 2^31 entries.
PLACEDB_SURF_AVX2 void HaarBatchAvx2(const IntegralImage& ii, const HaarOffsets& o, const float* xs,
                                     const float* ys, int n, float* dx, float* dy) {
  const long long* table = reinterpret_cast<const long long*>(ii.data());
  const __m256 lift = _mm256_set1_ps(0.5f * static_cast<float>(o.h - 1));
  const __m256i stride = _mm256_set1_epi32(o.stride);
  // Anchors of points 0 1 4 5 in the low half, 2 3 6 7 in the high half
  // (see GatherPair).
  const __m256i order = _mm256_setr_epi32(0, 1, 4, 5, 2, 3, 6, 7);
  const int s = o.stride;
  const int rh = static_cast<int>(o.row_half);
  const int rf = static_cast<int>(o.row_full);
  const __m256 one = _mm256_set1_ps(1.f);
  int i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256 fx0 = _mm256_sub_ps(_mm256_loadu_ps(xs + i), lift);
    const __m256 fy0 = _mm256_sub_ps(_mm256_loadu_ps(ys + i), lift);
    const __m256 flx = _mm256_floor_ps(fx0);
    const __m256 fly = _mm256_floor_ps(fy0);
    const __m256 fx = _mm256_sub_ps(fx0, flx);
    const __m256 fy = _mm256_sub_ps(fy0, fly);
    const __m256i base = _mm256_permutevar8x32_epi32(
        _mm256_add_epi32(_mm256_mullo_epi32(_mm256_cvttps_epi32(fly), stride),
                         _mm256_cvttps_epi32(flx)),
        order);
    const __m128i base_a = _mm256_castsi256_si128(base);
    const __m128i base_b = _mm256_extracti128_si256(base, 1);
    __m256 rx[4], ry[4];
    for (int row = 0; row < 2; ++row) {  // Anchors p + row * stride (+ 1).
      const int r = row * s;
      __m256i a00[2], a01[2], a02[2], a10[2], a12[2], a20[2], a21[2], a22[2];
      GatherPair(table, base_a, base_b, r, &a00[0], &a00[1]);
      GatherPair(table, base_a, base_b, r + o.half, &a01[0], &a01[1]);
      GatherPair(table, base_a, base_b, r + o.h, &a02[0], &a02[1]);
      GatherPair(table, base_a, base_b, r + rh, &a10[0], &a10[1]);
      GatherPair(table, base_a, base_b, r + rh + o.h, &a12[0], &a12[1]);
      GatherPair(table, base_a, base_b, r + rf, &a20[0], &a20[1]);
      GatherPair(table, base_a, base_b, r + rf + o.half, &a21[0], &a21[1]);
      GatherPair(table, base_a, base_b, r + rf + o.h, &a22[0], &a22[1]);
      for (int col = 0; col < 2; ++col) {
        HaarFromEntries(a00[col], a01[col], a02[col], a10[col], a12[col], a20[col], a21[col],
                        a22[col], &rx[2 * row + col], &ry[2 * row + col]);
      }
    }
    // Blend along x, then along y, as HaarSubPixel: no FMA, so that both
    // paths round identically.
    const __m256 gx_ = _mm256_sub_ps(one, fx);
    const __m256 gy_ = _mm256_sub_ps(one, fy);
    const __m256 top_x = _mm256_add_ps(_mm256_mul_ps(gx_, rx[0]), _mm256_mul_ps(fx, rx[1]));
    const __m256 bot_x = _mm256_add_ps(_mm256_mul_ps(gx_, rx[2]), _mm256_mul_ps(fx, rx[3]));
    const __m256 top_y = _mm256_add_ps(_mm256_mul_ps(gx_, ry[0]), _mm256_mul_ps(fx, ry[1]));
    const __m256 bot_y = _mm256_add_ps(_mm256_mul_ps(gx_, ry[2]), _mm256_mul_ps(fx, ry[3]));
    _mm256_storeu_ps(dx + i, _mm256_add_ps(_mm256_mul_ps(gy_, top_x), _mm256_mul_ps(fy, bot_x)));
    _mm256_storeu_ps(dy + i, _mm256_add_ps(_mm256_mul_ps(gy_, top_y), _mm256_mul_ps(fy, bot_y)));
  }
  HaarBatchPlain(ii, o, xs + i, ys + i, n - i, dx + i, dy + i);
}
#endif

// Sub-pixel Haar responses at n points whose boxes (and one pixel more right
// and down) lie inside the image, with the kernel of the copy being compiled.
template <SurfSimd kSimd>
PLACEDB_SURF_INLINE void HaarBatch(const IntegralImage& ii, const HaarOffsets& o, const float* xs,
                                   const float* ys, int n, float* dx, float* dy) {
#if defined(PLACEDB_SURF_X86)
  if constexpr (kSimd == SurfSimd::kAvx2) {
    if (static_cast<int64_t>(ii.rows() + 1) * ii.stride() < (int64_t{1} << 31)) {
      HaarBatchAvx2(ii, o, xs, ys, n, dx, dy);
      return;
    }
  }
#endif
  HaarBatchPlain(ii, o, xs, ys, n, dx, dy);
}

// atan2 in degrees in [0, 360), about 0.01 degree error (polynomial for
// atan on [0, 1]). Branch-free, so that loops over it vectorise (with
// -fno-trapping-math, which lets the compiler evaluate both sides of a select).
PLACEDB_SURF_INLINE float FastAtan2Deg(float y, float x) {
  constexpr float kRad2Deg = 57.2957795130823f;
  constexpr float p1 = 0.9997878412794807f * kRad2Deg;
  constexpr float p3 = -0.3258083974640975f * kRad2Deg;
  constexpr float p5 = 0.1555786518463281f * kRad2Deg;
  constexpr float p7 = -0.04432655554792128f * kRad2Deg;
  const float ax = std::abs(x), ay = std::abs(y);
  const bool x_major = ax >= ay;
  const float num = x_major ? ay : ax;
  const float den = x_major ? ax : ay;
  const float c = num / (den + 1e-10f);
  const float c2 = c * c;
  const float t = (((p7 * c2 + p5) * c2 + p3) * c2 + p1) * c;
  float a = x_major ? t : 90.f - t;
  a = x < 0 ? 180.f - a : a;
  a = y < 0 ? 360.f - a : a;
  return a >= 360.f ? a - 360.f : a;
}

struct OriTable {
  // Sample offsets (units of s) and Gaussian weights; padding has weight 0.
  alignas(32) float i[kMaxOriSamples];
  alignas(32) float j[kMaxOriSamples];
  alignas(32) float weight[kMaxOriSamples];
  int count = 0;  // Real samples (109).
  OriTable() {
    for (int b = -kOriRadius; b <= kOriRadius; ++b) {
      for (int a = -kOriRadius; a <= kOriRadius; ++a) {
        const int r2 = a * a + b * b;
        if (r2 >= kOriRadius * kOriRadius) continue;
        i[count] = static_cast<float>(a);
        j[count] = static_cast<float>(b);
        weight[count] = std::exp(-r2 / (2.f * kOriSigma * kOriSigma));
        ++count;
      }
    }
    for (int k = count; k < kMaxOriSamples; ++k) i[k] = j[k] = weight[k] = 0.f;
  }
};

// Descriptor samples in the order index = p * 16 + k, where k = 4 * row + col
// is the sub-region and p = 5 * row + col the sample inside it, so summing a
// sub-region's samples is an element-wise add over 16 lanes.
struct DescTable {
  alignas(32) float u[kNumSamples];       // Column offset in units of s.
  alignas(32) float v[kNumSamples];       // Row offset in units of s.
  alignas(32) float weight[kNumSamples];  // Gaussian, sigma 3.3 s.
  DescTable() {
    for (int p = 0; p < kSub * kSub; ++p) {
      for (int k = 0; k < kNumSub; ++k) {
        const int row = (k / 4) * kSub + p / kSub;
        const int col = (k % 4) * kSub + p % kSub;
        const int idx = p * kNumSub + k;
        u[idx] = static_cast<float>(col) - 9.5f;
        v[idx] = static_cast<float>(row) - 9.5f;
        weight[idx] =
            std::exp(-(u[idx] * u[idx] + v[idx] * v[idx]) / (2.f * kDescSigma * kDescSigma));
      }
    }
  }
};

const OriTable& Ori() {
  static const OriTable table;
  return table;
}

const DescTable& Desc() {
  static const DescTable table;
  return table;
}

// True when every sub-pixel Haar box of side h centred within `radius` of
// (x, y) lies inside the image.
PLACEDB_SURF_INLINE bool FitsInside(const IntegralImage& ii, float x, float y, float radius,
                                    int h) {
  const float m = radius + 0.5f * static_cast<float>(h) + 2.f;
  return x - m >= 0.f && y - m >= 0.f && x + m <= static_cast<float>(ii.cols()) &&
         y + m <= static_cast<float>(ii.rows());
}

template <SurfSimd kSimd>
PLACEDB_SURF_INLINE float OrientationBody(const IntegralImage& ii, const cv::KeyPoint& kp,
                                          const OriTable& t) {
  const float s = ScaleOfSize(kp.size);
  const int h = std::max(2, 2 * Round(2.f * s));  // Haar side 4s, even.
  const HaarOffsets o(h, ii.stride());
  alignas(32) float xs[kMaxOriSamples], ys[kMaxOriSamples];
  alignas(32) float dx[kMaxOriSamples], dy[kMaxOriSamples];
  for (int k = 0; k < kMaxOriSamples; ++k) {
    xs[k] = kp.pt.x + t.i[k] * s;
    ys[k] = kp.pt.y + t.j[k] * s;
  }
  const int n = t.count;
  if (FitsInside(ii, kp.pt.x, kp.pt.y, kOriRadius * s, h)) {
    HaarBatch<kSimd>(ii, o, xs, ys, kMaxOriSamples, dx, dy);
  } else {
    for (int k = 0; k < kMaxOriSamples; ++k) {
      if (!HaarClamped(ii, o, xs[k], ys[k], &dx[k], &dy[k])) dx[k] = dy[k] = 0.f;
    }
  }
  // Responses go to angular bins of 3 degrees; the 60-degree window slides
  // bin by bin around the circle (OpenCV slides in 5-degree steps). Angles
  // and weighted responses of all samples first (vectorised), then the
  // scatter into the bins.
  alignas(32) int bins[kMaxOriSamples];
  alignas(32) float wx[kMaxOriSamples], wy[kMaxOriSamples];
  for (int k = 0; k < kMaxOriSamples; ++k) {
    const int bin = static_cast<int>(FastAtan2Deg(dy[k], dx[k]) * (kOriBins / 360.f));
    bins[k] = bin >= kOriBins ? kOriBins - 1 : bin;
    wx[k] = t.weight[k] * dx[k];
    wy[k] = t.weight[k] * dy[k];
  }
  float bin_x[kOriBins] = {};
  float bin_y[kOriBins] = {};
  bool any = false;
  for (int k = 0; k < n; ++k) {
    if (dx[k] == 0.f && dy[k] == 0.f) continue;
    bin_x[bins[k]] += wx[k];
    bin_y[bins[k]] += wy[k];
    any = true;
  }
  if (!any) return 0.f;
  float sum_x = 0.f, sum_y = 0.f;
  for (int b = 0; b < kOriWindowBins; ++b) {
    sum_x += bin_x[b];
    sum_y += bin_y[b];
  }
  float best = sum_x * sum_x + sum_y * sum_y, best_x = sum_x, best_y = sum_y;
  for (int b = 0; b + 1 < kOriBins; ++b) {
    // Window [b + 1, b + kOriWindowBins] (mod kOriBins).
    const int in =
        b + kOriWindowBins < kOriBins ? b + kOriWindowBins : b + kOriWindowBins - kOriBins;
    sum_x += bin_x[in] - bin_x[b];
    sum_y += bin_y[in] - bin_y[b];
    const float len2 = sum_x * sum_x + sum_y * sum_y;
    if (len2 > best) {
      best = len2;
      best_x = sum_x;
      best_y = sum_y;
    }
  }
  return FastAtan2Deg(best_y, best_x);
}

// Per sub-region sums of the 25 samples (lanes k of each p), in the window's
// axes, Gaussian weighted.
PLACEDB_SURF_INLINE void AccumulateBasic(const float* dx, const float* dy, const float* weight,
                                         float co, float si, float acc[8][kNumSub]) {
  for (int p = 0; p < kSub * kSub; ++p) {
    const int base = p * kNumSub;
    for (int k = 0; k < kNumSub; ++k) {
      const float w = weight[base + k];
      const float gx = dx[base + k], gy = dy[base + k];
      const float du = w * (gx * co + gy * si);
      const float dv = w * (gy * co - gx * si);
      acc[0][k] += du;
      acc[1][k] += dv;
      acc[2][k] += std::abs(du);
      acc[3][k] += std::abs(dv);
    }
  }
}

PLACEDB_SURF_INLINE void AccumulateExtended(const float* dx, const float* dy, const float* weight,
                                            float co, float si, float acc[8][kNumSub]) {
  for (int p = 0; p < kSub * kSub; ++p) {
    const int base = p * kNumSub;
    for (int k = 0; k < kNumSub; ++k) {
      const float w = weight[base + k];
      const float gx = dx[base + k], gy = dy[base + k];
      const float du = w * (gx * co + gy * si);
      const float dv = w * (gy * co - gx * si);
      const bool dv_neg = dv < 0.f, du_neg = du < 0.f;
      acc[0][k] += dv_neg ? du : 0.f;
      acc[1][k] += dv_neg ? std::abs(du) : 0.f;
      acc[2][k] += dv_neg ? 0.f : du;
      acc[3][k] += dv_neg ? 0.f : std::abs(du);
      acc[4][k] += du_neg ? dv : 0.f;
      acc[5][k] += du_neg ? std::abs(dv) : 0.f;
      acc[6][k] += du_neg ? 0.f : dv;
      acc[7][k] += du_neg ? 0.f : std::abs(dv);
    }
  }
}

template <SurfSimd kSimd>
PLACEDB_SURF_INLINE void DescriptorBody(const IntegralImage& ii, const cv::KeyPoint& kp,
                                        bool upright, bool extended, const DescTable& t,
                                        float* out) {
  const int dim = extended ? 128 : 64;
  const float s = ScaleOfSize(kp.size);
  const int h = std::max(2, 2 * Round(s));  // Haar side 2s, even.
  const HaarOffsets o(h, ii.stride());
  float co = 1.f, si = 0.f;
  if (!upright) {
    const float a = kp.angle * (kPi / 180.f);
    co = std::cos(a);
    si = std::sin(a);
  }
  // Sample positions: the window's u axis is the orientation.
  const float ux = s * co, uy = s * si, vx = -s * si, vy = s * co;
  const float cx = kp.pt.x, cy = kp.pt.y;
  alignas(32) float xs[kNumSamples], ys[kNumSamples], dx[kNumSamples], dy[kNumSamples];
  for (int k = 0; k < kNumSamples; ++k) {
    xs[k] = cx + t.u[k] * ux + t.v[k] * vx;
    ys[k] = cy + t.u[k] * uy + t.v[k] * vy;
  }
  // Farthest sample centre: 9.5 s along both axes.
  if (FitsInside(ii, cx, cy, 9.5f * 1.41422f * s, h)) {
    HaarBatch<kSimd>(ii, o, xs, ys, kNumSamples, dx, dy);
  } else {
    for (int k = 0; k < kNumSamples; ++k) {
      if (!HaarClamped(ii, o, xs[k], ys[k], &dx[k], &dy[k])) dx[k] = dy[k] = 0.f;
    }
  }
  alignas(32) float acc[8][kNumSub] = {};
  if (extended) {
    AccumulateExtended(dx, dy, t.weight, co, si, acc);
  } else {
    AccumulateBasic(dx, dy, t.weight, co, si, acc);
  }
  const int per_sub = extended ? 8 : 4;
  for (int k = 0; k < kNumSub; ++k) {
    for (int c = 0; c < per_sub; ++c) out[k * per_sub + c] = acc[c][k];
  }
  double norm2 = 0.0;
  for (int k = 0; k < dim; ++k) norm2 += static_cast<double>(out[k]) * out[k];
  if (norm2 > 0.0) {
    const float inv = static_cast<float>(1.0 / std::sqrt(norm2));
    for (int k = 0; k < dim; ++k) out[k] *= inv;
  }
}

float OrientationPlain(const IntegralImage& ii, const cv::KeyPoint& kp, const OriTable& t) {
  return OrientationBody<SurfSimd::kPlain>(ii, kp, t);
}

void DescriptorPlain(const IntegralImage& ii, const cv::KeyPoint& kp, bool upright, bool extended,
                     const DescTable& t, float* out) {
  DescriptorBody<SurfSimd::kPlain>(ii, kp, upright, extended, t, out);
}

#if defined(PLACEDB_SURF_X86)
PLACEDB_SURF_AVX2 float OrientationAvx2(const IntegralImage& ii, const cv::KeyPoint& kp,
                                        const OriTable& t) {
  return OrientationBody<SurfSimd::kAvx2>(ii, kp, t);
}

PLACEDB_SURF_AVX2 void DescriptorAvx2(const IntegralImage& ii, const cv::KeyPoint& kp, bool upright,
                                      bool extended, const DescTable& t, float* out) {
  DescriptorBody<SurfSimd::kAvx2>(ii, kp, upright, extended, t, out);
}
#endif

}  // namespace

float ComputeOrientation(const IntegralImage& ii, const cv::KeyPoint& kp) {
  if (ii.rows() == 0 || ii.cols() == 0) return 0.f;
  const OriTable& t = Ori();
#if defined(PLACEDB_SURF_X86)
  if (SurfSimdActive() == SurfSimd::kAvx2) return OrientationAvx2(ii, kp, t);
#endif
  return OrientationPlain(ii, kp, t);
}

void ComputeDescriptor(const IntegralImage& ii, const cv::KeyPoint& kp, bool upright, bool extended,
                       float* out) {
  std::fill(out, out + (extended ? 128 : 64), 0.f);
  if (ii.rows() == 0 || ii.cols() == 0) return;
  const DescTable& t = Desc();
#if defined(PLACEDB_SURF_X86)
  if (SurfSimdActive() == SurfSimd::kAvx2) {
    DescriptorAvx2(ii, kp, upright, extended, t, out);
    return;
  }
#endif
  DescriptorPlain(ii, kp, upright, extended, t, out);
}

}  // namespace surf_internal
}  // namespace placedb
