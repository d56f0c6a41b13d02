// Run-time SIMD dispatch of SURF's hot loops. Internal to the SURF module.
//
// How it works: each hot loop (Fast-Hessian rows, non-maximum candidates,
// Haar responses, orientation, descriptor) is written once as an
// always-inline body and compiled twice in its own translation unit: a plain
// copy for the baseline target of the build (plain x86-64 for the shipped
// Release build) and a copy marked PLACEDB_SURF_AVX2, i.e.
// __attribute__((target("avx2,fma"))), which the compiler vectorises for
// AVX2. Callers pick one by SurfSimdActive(), decided once from the CPU
// (cpuid, including the OS's YMM state support) in a function-local static:
// no IFUNC (target_clones), no global constructor, no -mavx2 translation
// unit whose inline functions the linker could hand to baseline callers. This
// keeps ThreadSanitizer binaries working (TSan cannot run IFUNC resolvers at
// load time) and the default build fast on any x86-64.
//
// Both copies compute the same operations in the same order and the library
// is built with -ffp-contract=off (no fused multiply-add contraction), so the
// two paths give bit-identical keypoints and descriptors; surf_test checks it.
//
// Forcing the plain path:
//  - environment variable PLACEDB_SURF_SIMD=0 (read once, at SURF's first
//    use in the process; any other value, or unset, means "use the CPU's
//    best"), e.g. to compare whole runs;
//  - SetSurfSimdForTesting(false) at run time (tests, benchmarks).
#pragma once

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define PLACEDB_SURF_X86 1
// The AVX2+FMA copy of a hot function. Never call one unless
// SurfSimdActive() == SurfSimd::kAvx2.
#define PLACEDB_SURF_AVX2 __attribute__((target("avx2,fma")))
#endif

#if defined(__GNUC__) || defined(__clang__)
// Bodies shared by both copies: always inlined, so that each copy compiles
// them for its own target.
#define PLACEDB_SURF_INLINE inline __attribute__((always_inline))
#else
#define PLACEDB_SURF_INLINE inline
#endif

namespace placedb {
namespace surf_internal {

enum class SurfSimd {
  kPlain,  // Baseline target of the build.
  kAvx2,   // AVX2 + FMA (x86-64 only).
};

// The best level of this CPU, unless PLACEDB_SURF_SIMD=0. Computed once.
SurfSimd SurfSimdSupported();

// The level the hot loops use now: SurfSimdSupported(), or kPlain while
// disabled by SetSurfSimdForTesting(false). Cheap (one relaxed atomic load).
SurfSimd SurfSimdActive();

// For tests and benchmarks: false forces the plain path, true restores
// SurfSimdSupported(). Process-wide, takes effect at the next SURF call;
// returns the previous setting.
bool SetSurfSimdForTesting(bool enabled);

// "avx2+fma" or "plain".
const char* SurfSimdName(SurfSimd level);

}  // namespace surf_internal
}  // namespace placedb
