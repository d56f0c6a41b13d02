#include "placedb/match/hamming.h"

#include <cstring>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define PLACEDB_X86 1
#endif

namespace placedb {
namespace {

struct ByteTable {
  uint8_t bits[256];
  ByteTable() {
    for (int i = 0; i < 256; ++i) bits[i] = static_cast<uint8_t>(__builtin_popcount(i) & 0xff);
  }
};
const ByteTable kTable;

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
      out.Update(dist, j);
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
  for (; j < count; ++j) {
    out.Update(HammingPopcnt(query, db + static_cast<size_t>(j) * 32, 32), j);
  }
  return out;
}
#endif

using Kernel = HammingKernel;

Kernel DetectKernel() {
#if PLACEDB_X86
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt")) return Kernel::kAvx2;
  if (__builtin_cpu_supports("popcnt")) return Kernel::kPopcnt;
#endif
  return Kernel::kReference;
}

const Kernel kKernel = DetectKernel();

}  // namespace

uint32_t HammingReference(const uint8_t* a, const uint8_t* b, int bytes) {
  uint32_t total = 0;
  for (int i = 0; i < bytes; ++i) total += kTable.bits[a[i] ^ b[i]];
  return total;
}

uint32_t Hamming(const uint8_t* a, const uint8_t* b, int bytes) {
#if PLACEDB_X86
  if (kKernel != Kernel::kReference) return HammingPopcnt(a, b, bytes);
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
#if PLACEDB_X86
  if (kKernel == Kernel::kAvx2) return TwoNearestAvx2(query, db, count, bytes);
  if (kKernel == Kernel::kPopcnt) return TwoNearestPopcnt(query, db, count, bytes);
#endif
  return TwoNearestHammingReference(query, db, count, bytes);
}

bool HammingKernelAvailable(HammingKernel kernel) {
  switch (kernel) {
    case Kernel::kReference:
      return true;
    case Kernel::kPopcnt:
      return kKernel == Kernel::kPopcnt || kKernel == Kernel::kAvx2;
    case Kernel::kAvx2:
      return kKernel == Kernel::kAvx2;
  }
  return false;
}

TwoNearest TwoNearestHammingWith(HammingKernel kernel, const uint8_t* query, const uint8_t* db,
                                 int count, int bytes) {
  if (!HammingKernelAvailable(kernel)) kernel = Kernel::kReference;
#if PLACEDB_X86
  if (kernel == Kernel::kAvx2) return TwoNearestAvx2(query, db, count, bytes);
  if (kernel == Kernel::kPopcnt) return TwoNearestPopcnt(query, db, count, bytes);
#endif
  return TwoNearestHammingReference(query, db, count, bytes);
}

const char* HammingKernelName() {
  switch (kKernel) {
    case Kernel::kAvx2:
      return "avx2";
    case Kernel::kPopcnt:
      return "popcnt";
    case Kernel::kReference:
      return "reference";
  }
  return "reference";
}

}  // namespace placedb
