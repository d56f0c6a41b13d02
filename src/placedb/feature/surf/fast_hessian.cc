#include "placedb/feature/surf/fast_hessian.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "placedb/feature/surf/surf_simd.h"
#include "placedb/util/check.h"

#if defined(PLACEDB_SURF_X86)
#include <immintrin.h>
#endif

namespace placedb {
namespace surf_internal {
namespace {

// Relative weight of Dxy in the determinant (paper: 0.9, squared).
constexpr float kDxyWeight2 = 0.81f;

// Offsets of the distinct integral-image reads of one filter, relative to a
// cell's anchor. Row pointers are set per grid row, column offsets are fixed.
struct RowPointers {
  const uint32_t* xx[2];  // Dxx: top and bottom row of the lobes.
  const uint32_t* yy[4];  // Dyy: the four row borders of the three lobes.
  const uint32_t* xy[4];  // Dxy: the four row borders of the two lobe rows.
};

// Determinants of n consecutive cells of one grid row; cell i reads the
// integral image at column offset i * step from the pointers.
// kStep > 0 fixes the step at compile time (lets the compiler vectorise the
// contiguous case); kStep == 0 uses `step`. Compiled twice (HessianRowPlain,
// HessianRowAvx2; see surf_simd.h).
template <int kStep>
PLACEDB_SURF_INLINE void HessianRowBody(const RowPointers& p, int w, int len, int dxy_gap, int n,
                                        int step, float inv_xx, float inv_xy,
                                        float* __restrict out) {
  const uint32_t* __restrict xx0 = p.xx[0];
  const uint32_t* __restrict xx1 = p.xx[1];
  const uint32_t* __restrict yy0 = p.yy[0];
  const uint32_t* __restrict yy1 = p.yy[1];
  const uint32_t* __restrict yy2 = p.yy[2];
  const uint32_t* __restrict yy3 = p.yy[3];
  const uint32_t* __restrict xy0 = p.xy[0];
  const uint32_t* __restrict xy1 = p.xy[1];
  const uint32_t* __restrict xy2 = p.xy[2];
  const uint32_t* __restrict xy3 = p.xy[3];
  const int w2 = 2 * w;
  const int w3 = 3 * w;
  const int g = dxy_gap;
  const int gw = dxy_gap + w;
  for (int i = 0; i < n; ++i) {
    const int j = i * (kStep > 0 ? kStep : step);
    // Dxx: column sums of the lobe band at the four lobe borders.
    const uint32_t a0 = xx1[j] - xx0[j];
    const uint32_t a1 = xx1[j + w] - xx0[j + w];
    const uint32_t a2 = xx1[j + w2] - xx0[j + w2];
    const uint32_t a3 = xx1[j + w3] - xx0[j + w3];
    const int32_t dxx = static_cast<int32_t>(a3 - a0 + 3u * (a1 - a2));
    // Dyy: row sums of the lobe band at the four lobe borders.
    const uint32_t b0 = yy0[j + len] - yy0[j];
    const uint32_t b1 = yy1[j + len] - yy1[j];
    const uint32_t b2 = yy2[j + len] - yy2[j];
    const uint32_t b3 = yy3[j + len] - yy3[j];
    const int32_t dyy = static_cast<int32_t>(b3 - b0 + 3u * (b1 - b2));
    // Dxy: four w x w lobes, + top-left and bottom-right, - the others.
    const uint32_t tl = (xy1[j + w] - xy1[j]) - (xy0[j + w] - xy0[j]);
    const uint32_t tr = (xy1[j + gw] - xy1[j + g]) - (xy0[j + gw] - xy0[j + g]);
    const uint32_t bl = (xy3[j + w] - xy3[j]) - (xy2[j + w] - xy2[j]);
    const uint32_t br = (xy3[j + gw] - xy3[j + g]) - (xy2[j + gw] - xy2[j + g]);
    const int32_t dxy = static_cast<int32_t>(tl + br - tr - bl);
    const float fxx = static_cast<float>(dxx) * inv_xx;
    const float fyy = static_cast<float>(dyy) * inv_xx;
    const float fxy = static_cast<float>(dxy) * inv_xy;
    out[i] = fxx * fyy - kDxyWeight2 * fxy * fxy;
  }
}

template <int kStep>
void HessianRowPlain(const RowPointers& p, int w, int len, int dxy_gap, int n, int step,
                     float inv_xx, float inv_xy, float* __restrict out) {
  HessianRowBody<kStep>(p, w, len, dxy_gap, n, step, inv_xx, inv_xy, out);
}

#if defined(PLACEDB_SURF_X86)
template <int kStep>
PLACEDB_SURF_AVX2 void HessianRowAvx2(const RowPointers& p, int w, int len, int dxy_gap, int n,
                                      int step, float inv_xx, float inv_xy, float* __restrict out) {
  HessianRowBody<kStep>(p, w, len, dxy_gap, n, step, inv_xx, inv_xy, out);
}
#endif

template <int kStep>
void HessianRow(SurfSimd simd, const RowPointers& p, int w, int len, int dxy_gap, int n, int step,
                float inv_xx, float inv_xy, float* out) {
#if defined(PLACEDB_SURF_X86)
  if (simd == SurfSimd::kAvx2) {
    HessianRowAvx2<kStep>(p, w, len, dxy_gap, n, step, inv_xx, inv_xy, out);
    return;
  }
#endif
  HessianRowPlain<kStep>(p, w, len, dxy_gap, n, step, inv_xx, inv_xy, out);
}

// Candidates for a maximum in one grid row of a layer: writes the columns c
// in [begin, end) with d[c] > thr, d[c] > d[c - 1] and d[c] > d[c + 1] (the
// cheap part of the 3x3x3 test, done for whole rows) in increasing order and
// returns their number. d[begin - 1] and d[end] must be readable.
PLACEDB_SURF_INLINE int RowCandidatesPlain(const float* d, int begin, int end, float thr,
                                           int* out) {
  int n = 0;
  for (int c = begin; c < end; ++c) {
    const float v = d[c];
    out[n] = c;
    n += (v > thr) & (v > d[c - 1]) & (v > d[c + 1]);
  }
  return n;
}

#if defined(PLACEDB_SURF_X86)
PLACEDB_SURF_AVX2 int RowCandidatesAvx2(const float* d, int begin, int end, float thr, int* out) {
  const __m256 t = _mm256_set1_ps(thr);
  int n = 0;
  int c = begin;
  for (; c + 8 <= end; c += 8) {
    const __m256 v = _mm256_loadu_ps(d + c);
    const __m256 above = _mm256_cmp_ps(v, t, _CMP_GT_OQ);
    const __m256 left = _mm256_cmp_ps(v, _mm256_loadu_ps(d + c - 1), _CMP_GT_OQ);
    const __m256 right = _mm256_cmp_ps(v, _mm256_loadu_ps(d + c + 1), _CMP_GT_OQ);
    unsigned mask =
        static_cast<unsigned>(_mm256_movemask_ps(_mm256_and_ps(above, _mm256_and_ps(left, right))));
    while (mask != 0) {
      out[n++] = c + __builtin_ctz(mask);
      mask &= mask - 1;
    }
  }
  return n + RowCandidatesPlain(d, c, end, thr, out + n);
}
#endif

int RowCandidates(SurfSimd simd, const float* d, int begin, int end, float thr, int* out) {
#if defined(PLACEDB_SURF_X86)
  if (simd == SurfSimd::kAvx2) return RowCandidatesAvx2(d, begin, end, thr, out);
#endif
  return RowCandidatesPlain(d, begin, end, thr, out);
}

// One layer of determinants on an octave's sampling grid.
struct Layer {
  HessianFilter filter;
  int step = 1;
  // Cells whose filter lies inside the image: [r_lo, r_hi) x [c_lo, c_hi).
  int r_lo = 0, r_hi = 0, c_lo = 0, c_hi = 0;
  const float* det = nullptr;  // Grid of rows x cols; valid cells only.
};

// First and one-past-last grid index whose filter (anchored at
// index * step - size / 2, side size) lies inside [0, extent).
void ValidRange(int extent, int size, int step, int* lo, int* hi) {
  const int half = size / 2;
  *lo = (half + step - 1) / step;
  const int last_top = extent - size;  // Largest valid top-left pixel.
  *hi = last_top < 0 ? 0 : (last_top + half) / step + 1;
  if (*hi < *lo) *hi = *lo;
}

void ComputeLayer(SurfSimd simd, const IntegralImage& ii, const Layer& layer, int grid_cols,
                  float* det) {
  const HessianFilter& f = layer.filter;
  const int step = layer.step;
  const int half = f.size / 2;
  const int n = layer.c_hi - layer.c_lo;
  if (n <= 0) return;
  const int left = layer.c_lo * step - half;  // Left pixel of the first cell.
  const int w = f.lobe;
  for (int r = layer.r_lo; r < layer.r_hi; ++r) {
    const int top = r * step - half;
    RowPointers p;
    p.xx[0] = ii.Row(top + f.lobe_off) + left;
    p.xx[1] = ii.Row(top + f.lobe_off + f.lobe_len) + left;
    for (int k = 0; k < 4; ++k) p.yy[k] = ii.Row(top + k * w) + left + f.lobe_off;
    p.xy[0] = ii.Row(top + f.dxy_lo) + left + f.dxy_lo;
    p.xy[1] = ii.Row(top + f.dxy_lo + w) + left + f.dxy_lo;
    p.xy[2] = ii.Row(top + f.dxy_hi) + left + f.dxy_lo;
    p.xy[3] = ii.Row(top + f.dxy_hi + w) + left + f.dxy_lo;
    float* out = det + static_cast<size_t>(r) * grid_cols + layer.c_lo;
    const int gap = f.dxy_hi - f.dxy_lo;
    if (step == 1) {
      HessianRow<1>(simd, p, w, f.lobe_len, gap, n, 1, f.inv_area_xx, f.inv_area_xy, out);
    } else if (step == 2) {
      HessianRow<2>(simd, p, w, f.lobe_len, gap, n, 2, f.inv_area_xx, f.inv_area_xy, out);
    } else {
      HessianRow<0>(simd, p, w, f.lobe_len, gap, n, step, f.inv_area_xx, f.inv_area_xy, out);
    }
  }
}

// Solves the 3x3 system A x = b (A symmetric) by Cramer's rule; false when
// A is (nearly) singular.
bool Solve3x3(const float a[3][3], const float b[3], float x[3]) {
  const double d = a[0][0] * (double(a[1][1]) * a[2][2] - double(a[1][2]) * a[2][1]) -
                   a[0][1] * (double(a[1][0]) * a[2][2] - double(a[1][2]) * a[2][0]) +
                   a[0][2] * (double(a[1][0]) * a[2][1] - double(a[1][1]) * a[2][0]);
  if (!(std::abs(d) > 1e-12)) return false;
  const double inv = 1.0 / d;
  for (int k = 0; k < 3; ++k) {
    double m[3][3];
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) m[i][j] = (j == k) ? b[i] : a[i][j];
    }
    const double dk = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                      m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                      m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    x[k] = static_cast<float>(dk * inv);
  }
  return true;
}

}  // namespace

HessianFilter::HessianFilter(int octave, int layer) {
  const int base = 9 + 6 * layer;  // Odd side at octave 0.
  const int mult = 1 << octave;
  const int w0 = base / 3;      // Lobe width at octave 0 (odd).
  const int len0 = 2 * w0 - 1;  // Lobe length at octave 0.
  const int centre0 = (base - 1) / 2;
  size = base * mult;
  lobe = w0 * mult;
  lobe_len = len0 * mult;
  lobe_off = (base - len0) / 2 * mult;
  dxy_lo = (centre0 - w0) * mult;
  dxy_hi = (centre0 + 1) * mult;
  inv_area_xx = 1.0f / static_cast<float>(lobe * lobe_len);
  inv_area_xy = 1.0f / static_cast<float>(lobe * lobe);
}

void HessianFilter::Responses(const IntegralImage& ii, int top, int left, float* dxx, float* dyy,
                              float* dxy) const {
  const int w = lobe;
  const int32_t xx =
      ii.BoxSum(top + lobe_off, left, top + lobe_off + lobe_len, left + w) -
      2 * ii.BoxSum(top + lobe_off, left + w, top + lobe_off + lobe_len, left + 2 * w) +
      ii.BoxSum(top + lobe_off, left + 2 * w, top + lobe_off + lobe_len, left + 3 * w);
  const int32_t yy =
      ii.BoxSum(top, left + lobe_off, top + w, left + lobe_off + lobe_len) -
      2 * ii.BoxSum(top + w, left + lobe_off, top + 2 * w, left + lobe_off + lobe_len) +
      ii.BoxSum(top + 2 * w, left + lobe_off, top + 3 * w, left + lobe_off + lobe_len);
  const int32_t xy = ii.BoxSum(top + dxy_lo, left + dxy_lo, top + dxy_lo + w, left + dxy_lo + w) -
                     ii.BoxSum(top + dxy_lo, left + dxy_hi, top + dxy_lo + w, left + dxy_hi + w) -
                     ii.BoxSum(top + dxy_hi, left + dxy_lo, top + dxy_hi + w, left + dxy_lo + w) +
                     ii.BoxSum(top + dxy_hi, left + dxy_hi, top + dxy_hi + w, left + dxy_hi + w);
  *dxx = static_cast<float>(xx) * inv_area_xx;
  *dyy = static_cast<float>(yy) * inv_area_xx;
  *dxy = static_cast<float>(xy) * inv_area_xy;
}

void DetectFastHessian(const IntegralImage& ii, double threshold, int num_octaves,
                       int num_octave_layers, std::vector<cv::KeyPoint>* keypoints) {
  PLACEDB_CHECK(keypoints != nullptr);
  const int rows = ii.rows();
  const int cols = ii.cols();
  if (rows <= 0 || cols <= 0) return;
  const int num_layers = num_octave_layers + 2;
  const float thr = static_cast<float>(threshold);
  const SurfSimd simd = SurfSimdActive();
  std::vector<int> candidates(static_cast<size_t>(cols) + 8);
  std::vector<std::vector<float>> buffers(num_layers);
  std::vector<Layer> layers;
  layers.reserve(num_layers);

  for (int octave = 0; octave < num_octaves; ++octave) {
    const int step = 1 << octave;
    const int grid_rows = (rows - 1) / step + 1;
    const int grid_cols = (cols - 1) / step + 1;
    layers.clear();
    for (int l = 0; l < num_layers; ++l) {
      Layer layer{HessianFilter(octave, l)};
      layer.step = step;
      ValidRange(rows, layer.filter.size, step, &layer.r_lo, &layer.r_hi);
      ValidRange(cols, layer.filter.size, step, &layer.c_lo, &layer.c_hi);
      layers.push_back(layer);
    }
    // The largest filter must leave at least a 3x3 block of cells.
    const Layer& top_layer = layers.back();
    if (top_layer.r_hi - top_layer.r_lo < 3 || top_layer.c_hi - top_layer.c_lo < 3) break;
    for (int l = 0; l < num_layers; ++l) {
      buffers[l].resize(static_cast<size_t>(grid_rows) * grid_cols);
      ComputeLayer(simd, ii, layers[l], grid_cols, buffers[l].data());
      layers[l].det = buffers[l].data();
    }

    for (int l = 1; l <= num_octave_layers; ++l) {
      const Layer& above = layers[l + 1];
      const float* d0 = layers[l - 1].det;
      const float* d1 = layers[l].det;
      const float* d2 = above.det;
      const HessianFilter& f = layers[l].filter;
      const int ds = f.size - layers[l - 1].filter.size;
      const int half = f.size / 2;
      // Pixel centre offset of an anchor: top-left + (size - 1) / 2.
      const float shift = 0.5f * static_cast<float>(f.size - 1) - static_cast<float>(half);
      for (int r = above.r_lo + 1; r < above.r_hi - 1; ++r) {
        const size_t row = static_cast<size_t>(r) * grid_cols;
        const int num_candidates =
            RowCandidates(simd, d1 + row, above.c_lo + 1, above.c_hi - 1, thr, candidates.data());
        for (int ci = 0; ci < num_candidates; ++ci) {
          const int c = candidates[ci];
          const size_t idx = row + c;
          const float v = d1[idx];
          // 3x3x3 neighbourhood, strict maximum.
          bool is_max = true;
          for (int dr = -1; dr <= 1 && is_max; ++dr) {
            const size_t base = idx + static_cast<ptrdiff_t>(dr) * grid_cols;
            for (int dc = -1; dc <= 1; ++dc) {
              const size_t k = base + dc;
              if (d0[k] >= v || d2[k] >= v || (k != idx && d1[k] >= v)) {
                is_max = false;
                break;
              }
            }
          }
          if (!is_max) continue;
          // Quadratic fit of det(x, y, s) around the maximum.
          const size_t up = idx - grid_cols;
          const size_t dn = idx + grid_cols;
          const float grad[3] = {
              -0.5f * (d1[idx + 1] - d1[idx - 1]),
              -0.5f * (d1[dn] - d1[up]),
              -0.5f * (d2[idx] - d0[idx]),
          };
          float hess[3][3];
          hess[0][0] = d1[idx - 1] - 2 * v + d1[idx + 1];
          hess[1][1] = d1[up] - 2 * v + d1[dn];
          hess[2][2] = d0[idx] - 2 * v + d2[idx];
          hess[0][1] = hess[1][0] = 0.25f * (d1[dn + 1] - d1[dn - 1] - d1[up + 1] + d1[up - 1]);
          hess[0][2] = hess[2][0] = 0.25f * (d2[idx + 1] - d2[idx - 1] - d0[idx + 1] + d0[idx - 1]);
          hess[1][2] = hess[2][1] = 0.25f * (d2[dn] - d2[up] - d0[dn] + d0[up]);
          float off[3];
          if (!Solve3x3(hess, grad, off)) continue;
          if (!(std::abs(off[0]) <= 0.5f && std::abs(off[1]) <= 0.5f && std::abs(off[2]) <= 0.5f)) {
            continue;
          }
          // Sign of the Laplacian at the maximum.
          float dxx, dyy, dxy;
          f.Responses(ii, r * step - half, c * step - half, &dxx, &dyy, &dxy);
          const int laplacian_sign = (dxx + dyy) >= 0 ? 1 : -1;
          const float x = (static_cast<float>(c) + off[0]) * step + shift;
          const float y = (static_cast<float>(r) + off[1]) * step + shift;
          const float size = static_cast<float>(f.size) + off[2] * static_cast<float>(ds);
          keypoints->emplace_back(x, y, size, -1.0f, v, octave, laplacian_sign);
        }
      }
    }
  }
}

}  // namespace surf_internal
}  // namespace placedb
