#include "placedb/feature/surf/surf_simd.h"

#include <atomic>
#include <cstdlib>
#include <cstring>

namespace placedb {
namespace surf_internal {
namespace {

SurfSimd DetectSupported() {
  const char* env = std::getenv("PLACEDB_SURF_SIMD");
  if (env != nullptr && std::strcmp(env, "0") == 0) return SurfSimd::kPlain;
#if defined(PLACEDB_SURF_X86)
  // libgcc's (or compiler-rt's) cpuid reader; "avx2" is only reported when the
  // OS saves the YMM registers (XGETBV), so the AVX2 copy is safe to run.
  __builtin_cpu_init();
  if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return SurfSimd::kAvx2;
#endif
  return SurfSimd::kPlain;
}

// Function-local so that nothing runs at load time.
std::atomic<bool>& Enabled() {
  static std::atomic<bool> enabled{true};
  return enabled;
}

}  // namespace

SurfSimd SurfSimdSupported() {
  static const SurfSimd level = DetectSupported();
  return level;
}

SurfSimd SurfSimdActive() {
  return Enabled().load(std::memory_order_relaxed) ? SurfSimdSupported() : SurfSimd::kPlain;
}

bool SetSurfSimdForTesting(bool enabled) { return Enabled().exchange(enabled); }

const char* SurfSimdName(SurfSimd level) { return level == SurfSimd::kAvx2 ? "avx2+fma" : "plain"; }

}  // namespace surf_internal
}  // namespace placedb
