// Hamming distance kernels for binary descriptors (ORB: 32 bytes). Each fast
// kernel has a plain reference implementation it is tested against; the fast
// one is chosen once at run time from the CPU's features.
#pragma once

#include <cstdint>

#include "placedb/match/two_nearest.h"

namespace placedb {

// Distance between two `bytes`-long bit strings, byte table lookup.
uint32_t HammingReference(const uint8_t* a, const uint8_t* b, int bytes);

// The fastest available distance for any length (64-bit popcount when the
// CPU has POPCNT).
uint32_t Hamming(const uint8_t* a, const uint8_t* b, int bytes);

// The two smallest distances from `query` to `count` descriptors stored
// back to back (`bytes` each) at `db`, and the index of the smallest.
// Ties keep the lower index. With count == 0 both distances are UINT32_MAX
// and best_index is -1.
using TwoNearest = TwoNearestOf<uint32_t>;
TwoNearest TwoNearestHammingReference(const uint8_t* query, const uint8_t* db, int count,
                                      int bytes);
TwoNearest TwoNearestHamming(const uint8_t* query, const uint8_t* db, int count, int bytes);

// The kernels, for tests and benchmarks; TwoNearestHamming picks the best one
// this CPU runs.
enum class HammingKernel { kReference, kPopcnt, kAvx2 };
bool HammingKernelAvailable(HammingKernel kernel);
TwoNearest TwoNearestHammingWith(HammingKernel kernel, const uint8_t* query, const uint8_t* db,
                                 int count, int bytes);

// Name of the kernel TwoNearestHamming uses on this CPU ("avx2", "popcnt",
// "reference").
const char* HammingKernelName();

}  // namespace placedb
