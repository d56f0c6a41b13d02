#include "placedb/match/hamming.h"

#include "placedb/match/kernel_choice.h"

#if defined(__x86_64__) || defined(__i386__)
// GCC 12's AVX-512 headers trip -Wuninitialized on their own
// _mm512_undefined_epi32() (GCC bug 105593); the warnings point into the
// header, so they are silenced for it alone.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <immintrin.h>
#pragma GCC diagnostic pop
#define PLACEDB_X86 1
#endif

#include <spdlog/spdlog.h>

#include <cstdlib>
#include <cstring>
#include <vector>

namespace placedb {
namespace {

// Built at compile time, so it is usable from other translation units'
// static initialisers too.
struct ByteTable {
  uint8_t bits[256] = {};
  constexpr ByteTable() {
    for (int i = 0; i < 256; ++i) {
      int n = 0;
      for (int v = i; v != 0; v >>= 1) n += v & 1;
      bits[i] = static_cast<uint8_t>(n);
    }
  }
};
constexpr ByteTable kTable;

using Kernel = HammingKernel;

#if PLACEDB_X86
__attribute__((target("popcnt"))) uint32_t HammingPopcnt(const uint8_t* a, const uint8_t* b,
                                                         int bytes) {
  uint32_t total = 0;
  int i = 0;
  for (; i + 8 <= bytes; i += 8) {
    uint64_t x, y;
    std::memcpy(&x, a + i, 8);
    std::memcpy(&y, b + i, 8);
    total += static_cast<uint32_t>(_mm_popcnt_u64(x ^ y));
  }
  for (; i < bytes; ++i) total += kTable.bits[a[i] ^ b[i]];
  return total;
}

__attribute__((target("popcnt"))) TwoNearest TwoNearestPopcnt(const uint8_t* query,
                                                              const uint8_t* db, int count,
                                                              int bytes) {
  TwoNearest out;
  if (bytes == 32) {
    uint64_t q[4];
    std::memcpy(q, query, 32);
    for (int j = 0; j < count; ++j) {
      uint64_t d[4];
      std::memcpy(d, db + static_cast<size_t>(j) * 32, 32);
      const uint32_t dist =
          static_cast<uint32_t>(_mm_popcnt_u64(q[0] ^ d[0]) + _mm_popcnt_u64(q[1] ^ d[1]) +
                                _mm_popcnt_u64(q[2] ^ d[2]) + _mm_popcnt_u64(q[3] ^ d[3]));
      // TwoNearest::Update without branches (conditional moves): which row
      // is nearer is a coin flip for the branch predictor, and guided
      // matching calls this for a few rows at a time.
      const bool nearer = dist < out.best;
      const uint32_t second = dist < out.second ? dist : out.second;
      out.second = nearer ? out.best : second;
      out.best_index = nearer ? j : out.best_index;
      out.best = nearer ? dist : out.best;
    }
    return out;
  }
  for (int j = 0; j < count; ++j) {
    out.Update(HammingPopcnt(query, db + static_cast<size_t>(j) * bytes, bytes), j);
  }
  return out;
}

__attribute__((target("avx2"))) inline __m256i PopcountBytesAvx2(__m256i v, __m256i lut,
                                                                 __m256i low_mask) {
  const __m256i lo = _mm256_and_si256(v, low_mask);
  const __m256i hi = _mm256_and_si256(_mm256_srli_epi16(v, 4), low_mask);
  return _mm256_add_epi8(_mm256_shuffle_epi8(lut, lo), _mm256_shuffle_epi8(lut, hi));
}

// AVX2: popcount of 32-byte XORs by the nibble-lookup method (Mula), four
// database descriptors per step so the horizontal sums are shared.
__attribute__((target("avx2,popcnt"))) TwoNearest TwoNearestAvx2(const uint8_t* query,
                                                                 const uint8_t* db, int count,
                                                                 int bytes) {
  if (bytes != 32) return TwoNearestPopcnt(query, db, count, bytes);
  TwoNearest out;
  const __m256i lut = _mm256_setr_epi8(0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4, 0, 1, 1, 2,
                                       1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4);
  const __m256i low_mask = _mm256_set1_epi8(0x0f);
  const __m256i zero = _mm256_setzero_si256();
  const __m256i q = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(query));
  int j = 0;
  for (; j + 4 <= count; j += 4) {
    const uint8_t* p = db + static_cast<size_t>(j) * 32;
    // Per descriptor: 4 partial sums (u64 lanes) of byte popcounts.
    const __m256i s0 = _mm256_sad_epu8(
        PopcountBytesAvx2(_mm256_xor_si256(q, _mm256_loadu_si256((const __m256i*)(p))), lut,
                          low_mask),
        zero);
    const __m256i s1 = _mm256_sad_epu8(
        PopcountBytesAvx2(_mm256_xor_si256(q, _mm256_loadu_si256((const __m256i*)(p + 32))), lut,
                          low_mask),
        zero);
    const __m256i s2 = _mm256_sad_epu8(
        PopcountBytesAvx2(_mm256_xor_si256(q, _mm256_loadu_si256((const __m256i*)(p + 64))), lut,
                          low_mask),
        zero);
    const __m256i s3 = _mm256_sad_epu8(
        PopcountBytesAvx2(_mm256_xor_si256(q, _mm256_loadu_si256((const __m256i*)(p + 96))), lut,
                          low_mask),
        zero);
    // Sums fit in 32 bits: pack lanes so one horizontal add serves four.
    // s01 lanes: [s0a+s0b... ] via unpack of 64-bit lanes.
    const __m256i s01 = _mm256_add_epi64(_mm256_unpacklo_epi64(s0, s1),
                                         _mm256_unpackhi_epi64(s0, s1));  // [d0,d1 | d0,d1]
    const __m256i s23 = _mm256_add_epi64(_mm256_unpacklo_epi64(s2, s3),
                                         _mm256_unpackhi_epi64(s2, s3));  // [d2,d3 | d2,d3]
    const __m128i t01 =
        _mm_add_epi64(_mm256_castsi256_si128(s01), _mm256_extracti128_si256(s01, 1));  // d0, d1
    const __m128i t23 =
        _mm_add_epi64(_mm256_castsi256_si128(s23), _mm256_extracti128_si256(s23, 1));  // d2, d3
    alignas(16) uint64_t d[4];
    _mm_store_si128(reinterpret_cast<__m128i*>(d), t01);
    _mm_store_si128(reinterpret_cast<__m128i*>(d + 2), t23);
    out.Update(static_cast<uint32_t>(d[0]), j);
    out.Update(static_cast<uint32_t>(d[1]), j + 1);
    out.Update(static_cast<uint32_t>(d[2]), j + 2);
    out.Update(static_cast<uint32_t>(d[3]), j + 3);
  }
  // Explicit, not left to the compiler (GCC inserts it only from -O2 on):
  // the caller's SSE code must not pay for dirty upper halves.
  _mm256_zeroupper();
  for (; j < count; ++j) {
    out.Update(HammingPopcnt(query, db + static_cast<size_t>(j) * 32, 32), j);
  }
  return out;
}

// ---------------------------------------------------------------------------
// AVX-512 VPOPCNTDQ: 32 rows of 32 bytes per step, 16 zmm loads of two rows
// each, reduced to 32 distances in 16-bit lanes, where the per-lane best,
// second and row of the best are kept (16 bits: distances are <= 256, and
// rows are counted within chunks of 65536).
// Only ever called after HammingKernelAvailable(kAvx512) said yes.
#define PLACEDB_TARGET_AVX512 __attribute__((target("avx512f,avx512bw,avx512vl,avx512vpopcntdq")))
#define PLACEDB_INLINE_AVX512 PLACEDB_TARGET_AVX512 __attribute__((always_inline)) inline

// Row (within a step of 32) whose distance each 16-bit lane of
// Distances32() holds.
alignas(64) constexpr uint16_t kRowOfLane[32] = {0,  2,  16, 18, 4,  6,  20, 22, 8,  10, 24,
                                                 26, 12, 14, 28, 30, 1,  3,  17, 19, 5,  7,
                                                 21, 23, 9,  11, 25, 27, 13, 15, 29, 31};

// Rows per call of TwoNearestAvx512Chunk: row indices fit in 16 bits.
constexpr int kAvx512ChunkRows = 65536;
// Up to this many rows (at most 16) the AVX-512 kernels keep the rows in
// registers (FewNearest) instead of 32-row steps.
constexpr int kAvx512MinRows = 16;

#define PLACEDB_SHUFPS(a, b, imm) \
  _mm512_castps_si512(_mm512_shuffle_ps(_mm512_castsi512_ps(a), _mm512_castsi512_ps(b), (imm)))

// The distances of rows p[0..32) to the query `q2` (the 32-byte query in both
// halves of a zmm), in the lane order of kRowOfLane. With kMasked only the
// first `rest` rows are read (masked loads touch no other memory; the
// missing rows read as zeros and must be discarded by the caller).
template <bool kMasked>
PLACEDB_INLINE_AVX512 __m512i Distances32(__m512i q2, const uint8_t* p, int rest) {
  // c[k]: popcounts of the 64-bit words of rows 2k (words 0-3) and 2k+1
  // (words 4-7), each < 2^7 in the low half of its 64-bit lane.
  __m512i c[16];
  for (int k = 0; k < 16; ++k) {
    __m512i rows;
    if (kMasked) {
      int words = 4 * rest - 8 * k;  // 64-bit words of this load that exist
      words = words < 0 ? 0 : (words > 8 ? 8 : words);
      rows = _mm512_maskz_loadu_epi64(static_cast<__mmask8>((1u << words) - 1), p + 64 * k);
    } else {
      rows = _mm512_loadu_si512(p + 64 * k);
    }
    c[k] = _mm512_popcnt_epi64(_mm512_xor_si512(q2, rows));
  }
  // Pack: 32-bit lanes (c[2i] even, c[2i+1] odd), then 16-bit lanes (rows
  // 0-15 and 16-31 side by side in each 128-bit lane).
  __m512i w[4];
  for (int i = 0; i < 4; ++i) {
    const __m512i lo = _mm512_mask_shuffle_epi32(c[2 * i], 0xAAAA, c[2 * i + 1], _MM_PERM_CDAB);
    const __m512i hi =
        _mm512_mask_shuffle_epi32(c[8 + 2 * i], 0xAAAA, c[8 + 2 * i + 1], _MM_PERM_CDAB);
    w[i] = _mm512_packus_epi32(lo, hi);
  }
  // Add the two 64-bit words of each 128-bit half row (adjacent 32-bit
  // lanes), then the two half rows (in neighbouring 128-bit lanes).
  const __m512i n0 =
      _mm512_add_epi16(PLACEDB_SHUFPS(w[0], w[1], 0x88), PLACEDB_SHUFPS(w[0], w[1], 0xDD));
  const __m512i n1 =
      _mm512_add_epi16(PLACEDB_SHUFPS(w[2], w[3], 0x88), PLACEDB_SHUFPS(w[2], w[3], 0xDD));
  const __m512i cross = _mm512_setr_epi64(2, 3, 8, 9, 6, 7, 12, 13);
  return _mm512_add_epi16(_mm512_mask_blend_epi64(0xCC, n0, n1),
                          _mm512_permutex2var_epi64(n0, cross, n1));
}
#undef PLACEDB_SHUFPS

// (smallest, second smallest) per 16-bit lane: folds the pair (b1, b2) into
// (m1, m2) (each pair with x1 <= x2): (min of all four, second of all four).
PLACEDB_INLINE_AVX512 void FoldTwo(__m256i& m1, __m256i& m2, __m256i b1, __m256i b2) {
  m2 = _mm256_min_epu16(_mm256_max_epu16(m1, b1), _mm256_min_epu16(m2, b2));
  m1 = _mm256_min_epu16(m1, b1);
}
PLACEDB_INLINE_AVX512 void FoldTwo(__m128i& m1, __m128i& m2, __m128i b1, __m128i b2) {
  m2 = _mm_min_epu16(_mm_max_epu16(m1, b1), _mm_min_epu16(m2, b2));
  m1 = _mm_min_epu16(m1, b1);
}

// Per 16-bit lane: best, second and the first row of the step that gave the
// best (the lane's row is that + kRowOfLane[lane], < 2^16 within a chunk),
// among the rows that lane saw; they arrive in increasing index order, so
// strict < keeps the lower index.
struct Lanes {
  __m512i best, second, best_base;
};

PLACEDB_INLINE_AVX512 void Track(Lanes& s, __m512i d, int base) {
  const __mmask32 lt = _mm512_cmplt_epu16_mask(d, s.best);
  s.second = _mm512_min_epu16(s.second, _mm512_max_epu16(s.best, d));
  s.best = _mm512_min_epu16(s.best, d);
  s.best_base = _mm512_mask_mov_epi16(s.best_base, lt, _mm512_set1_epi16(static_cast<short>(base)));
}

// The two nearest over all lanes: the best, the lowest row among the lanes
// that have it, and the second smallest of every lane's best and second.
PLACEDB_INLINE_AVX512 TwoNearest ReduceLanes(const Lanes& lanes, __m512i row_of_lane) {
  // Across lanes, folding 512 -> 256 -> 128 bits, then within 128 bits.
  // The best, and the lowest row among the lanes that have it: the minimum
  // of (best << 16 | row) over the lanes, in 32 bits.
  const __m512i best = lanes.best, second = lanes.second;
  const __m512i row = _mm512_add_epi16(lanes.best_base, row_of_lane);
  const __m512i key512 =
      _mm512_min_epu32(_mm512_unpacklo_epi16(row, best), _mm512_unpackhi_epi16(row, best));
  const __m256i key256 =
      _mm256_min_epu32(_mm512_castsi512_si256(key512), _mm512_extracti64x4_epi64(key512, 1));
  __m128i key = _mm_min_epu32(_mm256_castsi256_si128(key256), _mm256_extracti128_si256(key256, 1));
  key = _mm_min_epu32(key, _mm_shuffle_epi32(key, _MM_SHUFFLE(1, 0, 3, 2)));
  key = _mm_min_epu32(key, _mm_shuffle_epi32(key, _MM_SHUFFLE(2, 3, 0, 1)));
  // The second: the second smallest of all lanes' best and second values
  // (= min(second of the winning lane, best of every other lane)), folding
  // (smallest, second smallest) pairs; independent of the key.
  __m256i a1 = _mm512_castsi512_si256(best), a2 = _mm512_castsi512_si256(second);
  FoldTwo(a1, a2, _mm512_extracti64x4_epi64(best, 1), _mm512_extracti64x4_epi64(second, 1));
  __m128i m1 = _mm256_castsi256_si128(a1), m2 = _mm256_castsi256_si128(a2);
  FoldTwo(m1, m2, _mm256_extracti128_si256(a1, 1), _mm256_extracti128_si256(a2, 1));
  FoldTwo(m1, m2, _mm_shuffle_epi32(m1, _MM_SHUFFLE(1, 0, 3, 2)),
          _mm_shuffle_epi32(m2, _MM_SHUFFLE(1, 0, 3, 2)));
  FoldTwo(m1, m2, _mm_shuffle_epi32(m1, _MM_SHUFFLE(2, 3, 0, 1)),
          _mm_shuffle_epi32(m2, _MM_SHUFFLE(2, 3, 0, 1)));
  FoldTwo(m1, m2, _mm_rol_epi32(m1, 16), _mm_rol_epi32(m2, 16));
  const uint32_t k = static_cast<uint32_t>(_mm_cvtsi128_si32(key));
  const uint32_t s = static_cast<uint32_t>(_mm_cvtsi128_si32(m2)) & 0xffff;
  TwoNearest out;
  out.best = k >> 16;  // count >= 1, so some lane has a candidate
  out.second = s == 0xffff ? UINT32_MAX : s;
  out.best_index = static_cast<int>(k & 0xffff);
  return out;
}

// At most kAvx512ChunkRows rows (count >= 1).
PLACEDB_TARGET_AVX512 TwoNearest TwoNearestAvx512Chunk(__m512i q2, const uint8_t* db, int count) {
  const __m512i none = _mm512_set1_epi16(-1);  // 0xffff: no candidate
  const __m512i row_of_lane = _mm512_load_si512(kRowOfLane);
  Lanes lanes{none, none, none};

  if (count < 32) {
    // Masked loads; the lanes of missing rows are set to 0xffff (never
    // < best, and max(best, d) = d leaves second as it is).
    const __m512i d = Distances32<true>(q2, db, count);
    const __mmask32 valid =
        _mm512_cmplt_epu16_mask(row_of_lane, _mm512_set1_epi16(static_cast<short>(count)));
    Track(lanes, _mm512_mask_mov_epi16(none, valid, d), 0);
  } else {
    int j = 0;
    for (; j + 32 <= count; j += 32) {
      Track(lanes, Distances32<false>(q2, db + static_cast<size_t>(j) * 32, 0), j);
    }
    if (j < count) {
      // 1..31 rows left: the last 32 rows again, keeping only the lanes of
      // rows >= j (those rows come after every row the lane saw).
      const int base = count - 32;
      const __m512i d = Distances32<false>(q2, db + static_cast<size_t>(base) * 32, 0);
      const __mmask32 fresh =
          _mm512_cmpge_epu16_mask(row_of_lane, _mm512_set1_epi16(static_cast<short>(j - base)));
      Track(lanes, _mm512_mask_mov_epi16(none, fresh, d), base);
    }
  }
  return ReduceLanes(lanes, row_of_lane);
}

// Up to 2 * kRegs rows (kRegs = 4 or 8), at most kAvx512MinRows, held in
// kRegs registers of two rows each (masked loads read only the rows that
// exist) and reused across queries: the four 64-bit popcounts of a row are
// summed within its 256-bit half, the row sums packed into 32-bit lanes,
// and the two nearest found by reductions over the lanes. No branch
// depends on the data, unlike a scan of a few rows, whose early loop exits
// the branch predictor misses (guided matching's rows of one vocabulary
// node, a node's children).
template <int kRegs>
struct FewRows {
  __m512i rows[kRegs];
  __mmask16 valid;  // 32-bit lanes (rows) that exist
  int count;
};

template <int kRegs>
PLACEDB_INLINE_AVX512 FewRows<kRegs> LoadFewRows(const uint8_t* db, int count) {
  FewRows<kRegs> f;
  for (int k = 0; k < kRegs; ++k) {
    int words = 4 * count - 8 * k;
    words = words < 0 ? 0 : (words > 8 ? 8 : words);
    f.rows[k] = _mm512_maskz_loadu_epi64(static_cast<__mmask8>((1u << words) - 1), db + 64 * k);
  }
  f.valid = static_cast<__mmask16>((1u << count) - 1);
  f.count = count;
  return f;
}

template <int kRegs>
PLACEDB_INLINE_AVX512 TwoNearest FewNearest(const FewRows<kRegs>& f, const uint8_t* query) {
  const __m512i q2 =
      _mm512_broadcast_i64x4(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(query)));
  // t[k]: row 2k's distance in every 64-bit lane of the low half, row
  // 2k + 1's in the high half.
  __m512i t[kRegs];
  for (int k = 0; k < kRegs; ++k) {
    const __m512i c = _mm512_popcnt_epi64(_mm512_xor_si512(q2, f.rows[k]));
    const __m512i pairs = _mm512_add_epi64(c, _mm512_shuffle_epi32(c, _MM_PERM_BADC));
    t[k] = _mm512_add_epi64(pairs, _mm512_shuffle_i64x2(pairs, pairs, _MM_SHUFFLE(2, 3, 0, 1)));
  }
  // Row r's distance to 32-bit lane r: pairs of registers, then pairs of
  // those (dword 0 and 8 of each t hold its two rows).
  const __m512i first = _mm512_setr_epi32(0, 8, 16, 24, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0);
  const __m512i second = _mm512_setr_epi32(0, 1, 2, 3, 16, 17, 18, 19, 0, 0, 0, 0, 0, 0, 0, 0);
  const __m512i third = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 16, 17, 18, 19, 20, 21, 22, 23);
  const __m512i p0 = _mm512_permutex2var_epi32(t[0], first, t[1]);
  const __m512i p1 = _mm512_permutex2var_epi32(t[2], first, t[3]);
  __m512i d = _mm512_permutex2var_epi32(p0, second, p1);  // rows 0-7
  if constexpr (kRegs == 8) {
    const __m512i p2 = _mm512_permutex2var_epi32(t[4], first, t[5]);
    const __m512i p3 = _mm512_permutex2var_epi32(t[6], first, t[7]);
    d = _mm512_permutex2var_epi32(d, third, _mm512_permutex2var_epi32(p2, second, p3));
  }
  const __m512i none = _mm512_set1_epi32(-1);
  d = _mm512_mask_mov_epi32(none, f.valid, d);
  TwoNearest out;
  const uint32_t best = _mm512_reduce_min_epu32(d);
  const uint32_t at = static_cast<uint32_t>(__builtin_ctz(static_cast<unsigned>(
      _mm512_cmpeq_epu32_mask(d, _mm512_set1_epi32(static_cast<int>(best))))));
  // The second: the smallest of the other lanes (a tie at the minimum
  // gives best again).
  const uint32_t next =
      _mm512_reduce_min_epu32(_mm512_mask_mov_epi32(d, static_cast<__mmask16>(1u << at), none));
  out.best = best;
  out.best_index = static_cast<int>(at);
  out.second = next;  // UINT32_MAX when there is no other row
  return out;
}

// TwoNearestAvx512 without the final vzeroupper (for loops over queries).
PLACEDB_TARGET_AVX512 TwoNearest TwoNearestAvx512Dirty(const uint8_t* query, const uint8_t* db,
                                                       int count) {
  const __m512i q2 =
      _mm512_broadcast_i64x4(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(query)));
  if (count <= kAvx512ChunkRows) return TwoNearestAvx512Chunk(q2, db, count);
  // Chunks in index order: a later chunk wins only when strictly better.
  TwoNearest out;
  for (int start = 0; start < count; start += kAvx512ChunkRows) {
    const int n = count - start < kAvx512ChunkRows ? count - start : kAvx512ChunkRows;
    const TwoNearest c = TwoNearestAvx512Chunk(q2, db + static_cast<size_t>(start) * 32, n);
    if (c.best < out.best) {
      out.second = out.best < c.second ? out.best : c.second;
      out.best = c.best;
      out.best_index = start + c.best_index;
    } else if (c.best < out.second) {
      out.second = c.best;
    }
  }
  return out;
}

// The two nearest of each of `num_queries` rows (32 bytes, back to back)
// among `count` rows, without the final vzeroupper. A few rows (guided
// matching's rows of one vocabulary node, a vocabulary node's children) are
// loaded into registers once for all the queries: a masked 32-row step and
// its reduction took 40-50 ns for any count below 32.
PLACEDB_INLINE_AVX512 void NearestAvx512Dirty(const uint8_t* queries, int num_queries,
                                              const uint8_t* db, int count, TwoNearest* out) {
  if (count <= 0) {
    for (int i = 0; i < num_queries; ++i) out[i] = TwoNearest();
  } else if (count <= 8) {
    const FewRows<4> rows = LoadFewRows<4>(db, count);
    for (int i = 0; i < num_queries; ++i)
      out[i] = FewNearest<4>(rows, queries + static_cast<size_t>(i) * 32);
  } else if (count <= kAvx512MinRows) {
    const FewRows<8> rows = LoadFewRows<8>(db, count);
    for (int i = 0; i < num_queries; ++i)
      out[i] = FewNearest<8>(rows, queries + static_cast<size_t>(i) * 32);
  } else {
    for (int i = 0; i < num_queries; ++i)
      out[i] = TwoNearestAvx512Dirty(queries + static_cast<size_t>(i) * 32, db, count);
  }
}

// GCC 12 emits no vzeroupper on these kernels' return: the caller's SSE code
// (the ratio test's double arithmetic) then paid a merge of the dirty upper
// halves on every instruction. Measured: the whole-keyframe match ran 1.5x
// slower than its distances. Every SIMD kernel leaves the upper state clean
// (hamming_test checks it).
PLACEDB_TARGET_AVX512 TwoNearest TwoNearestAvx512(const uint8_t* query, const uint8_t* db,
                                                  int count, int bytes) {
  if (bytes != 32) return TwoNearestPopcnt(query, db, count, bytes);
  TwoNearest out;
  NearestAvx512Dirty(query, 1, db, count, &out);
  _mm256_zeroupper();
  return out;
}

PLACEDB_TARGET_AVX512 void TwoNearestAvx512Batch(const uint8_t* queries, int num_queries,
                                                 const uint8_t* db, int count, TwoNearest* out) {
  NearestAvx512Dirty(queries, num_queries, db, count, out);
  _mm256_zeroupper();
}

// Per 16-bit lane of a step's 32 database rows (kRowOfLane order): the two
// nearest query rows, and the query row of the best, kept in memory as
// three rows of 32 u16 (best, second, best query). Query rows arrive in
// increasing order, so strict < keeps the lower one on ties.
PLACEDB_INLINE_AVX512 void TrackColumn(uint16_t* c, __m512i d, int query) {
  const __m512i best = _mm512_loadu_si512(c);
  const __m512i second = _mm512_loadu_si512(c + 32);
  const __m512i best_query = _mm512_loadu_si512(c + 64);
  const __mmask32 lt = _mm512_cmplt_epu16_mask(d, best);
  _mm512_storeu_si512(c + 32, _mm512_min_epu16(second, _mm512_max_epu16(best, d)));
  _mm512_storeu_si512(c, _mm512_min_epu16(best, d));
  _mm512_storeu_si512(
      c + 64, _mm512_mask_mov_epi16(best_query, lt, _mm512_set1_epi16(static_cast<short>(query))));
}

// Each query row's two nearest database rows (forward) and each database
// row's two nearest query rows (backward) from one pass over the distances.
// count >= 1, count <= kAvx512ChunkRows, 1 <= num_queries <= 65535.
PLACEDB_TARGET_AVX512 void TwoNearestAvx512Both(const uint8_t* queries, int num_queries,
                                                const uint8_t* db, int count, TwoNearest* forward,
                                                TwoNearest* backward) {
  const __m512i none = _mm512_set1_epi16(-1);
  const __m512i row_of_lane = _mm512_load_si512(kRowOfLane);
  // Steps of 32 rows; a last partial step (count % 32 rows) is the last 32
  // rows again (or, below 32 rows, a masked step), with the rows other steps
  // cover masked out.
  const int full = count / 32;
  const bool partial = count % 32 != 0;
  const int steps = full + (partial ? 1 : 0);
  const int partial_base = count < 32 ? 0 : count - 32;
  const __mmask32 partial_lanes =
      count < 32
          ? _mm512_cmplt_epu16_mask(row_of_lane, _mm512_set1_epi16(static_cast<short>(count)))
          : _mm512_cmpge_epu16_mask(
                row_of_lane, _mm512_set1_epi16(static_cast<short>(full * 32 - partial_base)));
  thread_local std::vector<uint16_t> columns;
  columns.assign(static_cast<size_t>(steps) * 96, 0xffff);
  for (int i = 0; i < num_queries; ++i) {
    const __m512i q2 = _mm512_broadcast_i64x4(_mm256_loadu_si256(
        reinterpret_cast<const __m256i*>(queries + static_cast<size_t>(i) * 32)));
    Lanes lanes{none, none, none};
    for (int k = 0; k < full; ++k) {
      const __m512i d = Distances32<false>(q2, db + static_cast<size_t>(k) * 1024, 0);
      Track(lanes, d, k * 32);
      TrackColumn(columns.data() + static_cast<size_t>(k) * 96, d, i);
    }
    if (partial) {
      const __m512i raw =
          count < 32 ? Distances32<true>(q2, db, count)
                     : Distances32<false>(q2, db + static_cast<size_t>(partial_base) * 32, 0);
      const __m512i d = _mm512_mask_mov_epi16(none, partial_lanes, raw);
      Track(lanes, d, partial_base);
      TrackColumn(columns.data() + static_cast<size_t>(full) * 96, d, i);
    }
    forward[i] = ReduceLanes(lanes, row_of_lane);
  }
  for (int k = 0; k < steps; ++k) {
    const uint16_t* best = columns.data() + static_cast<size_t>(k) * 96;
    const uint16_t* second = best + 32;
    const uint16_t* query = best + 64;
    const bool last = partial && k == full;
    const int base = last ? partial_base : k * 32;
    const uint32_t lanes = last ? partial_lanes : 0xffffffffu;
    for (int lane = 0; lane < 32; ++lane) {
      if (!((lanes >> lane) & 1u)) continue;
      TwoNearest& b = backward[base + kRowOfLane[lane]];
      b.best = best[lane];  // every column saw every query row
      b.second = second[lane] == 0xffff ? UINT32_MAX : second[lane];
      b.best_index = query[lane];
    }
  }
  _mm256_zeroupper();
}
#undef PLACEDB_INLINE_AVX512
#undef PLACEDB_TARGET_AVX512
#endif  // PLACEDB_X86

bool CpuRuns(Kernel kernel) {
#if PLACEDB_X86
  __builtin_cpu_init();
  switch (kernel) {
    case Kernel::kReference:
      return true;
    case Kernel::kPopcnt:
      return __builtin_cpu_supports("popcnt");
    case Kernel::kAvx2:
      return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt");
    case Kernel::kAvx512:
      // __builtin_cpu_supports also checks that the OS saves the zmm state.
      return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
             __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512vpopcntdq") &&
             __builtin_cpu_supports("popcnt");
  }
  return false;
#else
  return kernel == Kernel::kReference;
#endif
}

// What the CPU runs, computed once.
struct Support {
  bool runs[kNumHammingKernels];
  Kernel best = Kernel::kReference;
  Support() {
    for (int k = 0; k < kNumHammingKernels; ++k) {
      runs[k] = CpuRuns(static_cast<Kernel>(k));
      if (runs[k]) best = static_cast<Kernel>(k);  // kernels are listed slowest first
    }
  }
};

const Support& GetSupport() {
  static const Support support;
  return support;
}

TwoNearest Run(Kernel kernel, const uint8_t* query, const uint8_t* db, int count, int bytes) {
  switch (kernel) {
#if PLACEDB_X86
    case Kernel::kAvx512:
      return TwoNearestAvx512(query, db, count, bytes);
    case Kernel::kAvx2:
      return TwoNearestAvx2(query, db, count, bytes);
    case Kernel::kPopcnt:
      return TwoNearestPopcnt(query, db, count, bytes);
#endif
    default:
      return TwoNearestHammingReference(query, db, count, bytes);
  }
}

}  // namespace

uint32_t HammingReference(const uint8_t* a, const uint8_t* b, int bytes) {
  uint32_t total = 0;
  for (int i = 0; i < bytes; ++i) total += kTable.bits[a[i] ^ b[i]];
  return total;
}

uint32_t Hamming(const uint8_t* a, const uint8_t* b, int bytes) {
#if PLACEDB_X86
  if (ActiveHammingKernel() != Kernel::kReference) return HammingPopcnt(a, b, bytes);
#endif
  return HammingReference(a, b, bytes);
}

TwoNearest TwoNearestHammingReference(const uint8_t* query, const uint8_t* db, int count,
                                      int bytes) {
  TwoNearest out;
  for (int j = 0; j < count; ++j) {
    out.Update(HammingReference(query, db + static_cast<size_t>(j) * bytes, bytes), j);
  }
  return out;
}

TwoNearest TwoNearestHamming(const uint8_t* query, const uint8_t* db, int count, int bytes) {
  return Run(ActiveHammingKernel(), query, db, count, bytes);
}

void TwoNearestHammingBatchWith(HammingKernel kernel, const uint8_t* queries, int num_queries,
                                const uint8_t* db, int count, int bytes, TwoNearest* out) {
  if (!HammingKernelAvailable(kernel)) kernel = Kernel::kReference;
  const size_t stride = static_cast<size_t>(bytes);
#if PLACEDB_X86
  if (kernel == Kernel::kAvx512 && bytes == 32) {
    TwoNearestAvx512Batch(queries, num_queries, db, count, out);
    return;
  }
  if (kernel == Kernel::kAvx512 || kernel == Kernel::kPopcnt) {
    for (int i = 0; i < num_queries; ++i)
      out[i] = TwoNearestPopcnt(queries + i * stride, db, count, bytes);
    return;
  }
#endif
  for (int i = 0; i < num_queries; ++i)
    out[i] = Run(kernel, queries + i * stride, db, count, bytes);
}

void TwoNearestHammingBatch(const uint8_t* queries, int num_queries, const uint8_t* db, int count,
                            int bytes, TwoNearest* out) {
  TwoNearestHammingBatchWith(ActiveHammingKernel(), queries, num_queries, db, count, bytes, out);
}

namespace {
// Whether TwoNearestHammingBothWith computes each distance once: the
// AVX-512 kernel's limits (16-bit row indices within one chunk).
bool BothInOnePass(Kernel kernel, int num_queries, int count, int bytes) {
#if PLACEDB_X86
  return kernel == Kernel::kAvx512 && bytes == 32 && num_queries >= 1 && num_queries <= 65535 &&
         count >= 1 && count <= kAvx512ChunkRows;
#else
  (void)kernel, (void)num_queries, (void)count, (void)bytes;
  return false;
#endif
}
}  // namespace

void TwoNearestHammingBothWith(HammingKernel kernel, const uint8_t* queries, int num_queries,
                               const uint8_t* db, int count, int bytes, TwoNearest* forward,
                               TwoNearest* backward) {
  if (!HammingKernelAvailable(kernel)) kernel = Kernel::kReference;
#if PLACEDB_X86
  if (BothInOnePass(kernel, num_queries, count, bytes)) {
    TwoNearestAvx512Both(queries, num_queries, db, count, forward, backward);
    return;
  }
#endif
  TwoNearestHammingBatchWith(kernel, queries, num_queries, db, count, bytes, forward);
  TwoNearestHammingBatchWith(kernel, db, count, queries, num_queries, bytes, backward);
}

void TwoNearestHammingBoth(const uint8_t* queries, int num_queries, const uint8_t* db, int count,
                           int bytes, TwoNearest* forward, TwoNearest* backward) {
  TwoNearestHammingBothWith(ActiveHammingKernel(), queries, num_queries, db, count, bytes, forward,
                            backward);
}

bool HammingBothIsOnePass(int num_queries, int count, int bytes) {
  return BothInOnePass(ActiveHammingKernel(), num_queries, count, bytes);
}

bool HammingKernelAvailable(HammingKernel kernel) {
  const int k = static_cast<int>(kernel);
  return k >= 0 && k < kNumHammingKernels && GetSupport().runs[k];
}

TwoNearest TwoNearestHammingWith(HammingKernel kernel, const uint8_t* query, const uint8_t* db,
                                 int count, int bytes) {
  if (!HammingKernelAvailable(kernel)) kernel = Kernel::kReference;
  return Run(kernel, query, db, count, bytes);
}

HammingKernel BestHammingKernel() { return GetSupport().best; }

HammingKernel ChooseHammingKernel(const char* requested) {
  const char* (*name)(HammingKernel) = HammingKernelName;
  return internal::ChooseKernel(requested, "PLACEDB_HAMMING_KERNEL", kNumHammingKernels,
                                BestHammingKernel(), name, HammingKernelAvailable);
}

HammingKernel ActiveHammingKernel() {
  static const Kernel kernel = ChooseHammingKernel(std::getenv("PLACEDB_HAMMING_KERNEL"));
  return kernel;
}

const char* HammingKernelName(HammingKernel kernel) {
  switch (kernel) {
    case Kernel::kReference:
      return "reference";
    case Kernel::kPopcnt:
      return "popcnt";
    case Kernel::kAvx2:
      return "avx2";
    case Kernel::kAvx512:
      return "avx512";
  }
  return "unknown";
}

std::optional<HammingKernel> HammingKernelFromName(const char* name) {
  const char* (*kernel_name)(HammingKernel) = HammingKernelName;
  return internal::KernelFromName(name, kNumHammingKernels, kernel_name);
}

const char* HammingKernelName() { return HammingKernelName(ActiveHammingKernel()); }

}  // namespace placedb
