// Hamming distance kernels for binary descriptors (ORB: 32 bytes). Each fast
// kernel has a plain reference implementation it is tested against; the one
// TwoNearestHamming uses is chosen once, on first use, from the CPU's
// features, unless the environment variable PLACEDB_HAMMING_KERNEL
// (reference|popcnt|avx2|avx512) names another kernel the CPU can run.
#pragma once

#include <cstdint>
#include <optional>

#include "placedb/match/two_nearest.h"

namespace placedb {

// Distance between two `bytes`-long bit strings, byte table lookup.
uint32_t HammingReference(const uint8_t* a, const uint8_t* b, int bytes);

// The fastest available distance for any length (64-bit popcount unless the
// active kernel is the reference one).
uint32_t Hamming(const uint8_t* a, const uint8_t* b, int bytes);

// The two smallest distances from `query` to `count` descriptors stored
// back to back (`bytes` each) at `db`, and the index of the smallest.
// Ties keep the lower index (so `second == best` when two rows tie at the
// minimum). With count == 0 both distances are UINT32_MAX and best_index is
// -1.
using TwoNearest = TwoNearestOf<uint32_t>;
TwoNearest TwoNearestHammingReference(const uint8_t* query, const uint8_t* db, int count,
                                      int bytes);
TwoNearest TwoNearestHamming(const uint8_t* query, const uint8_t* db, int count, int bytes);

// TwoNearestHamming of each of `num_queries` query rows stored back to back
// (`bytes` each) at `queries`, against the same `count` rows at `db`, into
// out[0, num_queries): the same answers, with the kernel chosen once for
// the batch (guided matching's rows of one vocabulary node; a query against
// one keyframe).
void TwoNearestHammingBatch(const uint8_t* queries, int num_queries, const uint8_t* db, int count,
                            int bytes, TwoNearest* out);

// Both directions of a query against one keyframe: forward[i] =
// TwoNearestHamming(query row i, db, count), backward[j] =
// TwoNearestHamming(db row j, queries, num_queries), the same answers (ties:
// the lower index). The AVX-512 kernel computes each distance once for
// both (rows of 32 bytes, count <= 65536, num_queries < 65536); the others
// scan twice. HammingBothIsOnePass says whether a call with these sizes
// computes each distance once, with the active kernel.
void TwoNearestHammingBoth(const uint8_t* queries, int num_queries, const uint8_t* db, int count,
                           int bytes, TwoNearest* forward, TwoNearest* backward);
bool HammingBothIsOnePass(int num_queries, int count, int bytes);

// The kernels, for tests and benchmarks; TwoNearestHamming uses
// ActiveHammingKernel(). The numeric values are stable (benchmark arguments).
//   kReference: byte table, any CPU.
//   kPopcnt:    64-bit POPCNT, one row at a time.
//   kAvx2:      AVX2 nibble lookup, 4 rows per step (32-byte rows).
//   kAvx512:    AVX-512 VPOPCNTDQ, 32 rows per step (32-byte rows).
// The SIMD kernels handle any `bytes`: other lengths than 32 go to kPopcnt.
enum class HammingKernel { kReference = 0, kPopcnt = 1, kAvx2 = 2, kAvx512 = 3 };
constexpr int kNumHammingKernels = 4;

// Whether this CPU (and OS) can run `kernel`.
bool HammingKernelAvailable(HammingKernel kernel);

// TwoNearestHamming with the given kernel; a kernel this CPU cannot run is
// replaced by the reference one (never executes unsupported instructions).
TwoNearest TwoNearestHammingWith(HammingKernel kernel, const uint8_t* query, const uint8_t* db,
                                 int count, int bytes);
void TwoNearestHammingBatchWith(HammingKernel kernel, const uint8_t* queries, int num_queries,
                                const uint8_t* db, int count, int bytes, TwoNearest* out);
void TwoNearestHammingBothWith(HammingKernel kernel, const uint8_t* queries, int num_queries,
                               const uint8_t* db, int count, int bytes, TwoNearest* forward,
                               TwoNearest* backward);

// The fastest kernel this CPU runs, ignoring the environment.
HammingKernel BestHammingKernel();

// The kernel TwoNearestHamming uses: ChooseHammingKernel(getenv(
// "PLACEDB_HAMMING_KERNEL")), evaluated once on first use.
HammingKernel ActiveHammingKernel();

// The rule behind ActiveHammingKernel: `requested` (may be null or empty:
// no request) names a kernel; if the name is unknown or the CPU cannot run
// that kernel, logs one warning and returns BestHammingKernel().
HammingKernel ChooseHammingKernel(const char* requested);

// "reference", "popcnt", "avx2", "avx512" <-> kernel. Unknown names (or
// null): std::nullopt.
const char* HammingKernelName(HammingKernel kernel);
std::optional<HammingKernel> HammingKernelFromName(const char* name);

// Name of the kernel TwoNearestHamming uses (ActiveHammingKernel()).
const char* HammingKernelName();

}  // namespace placedb
