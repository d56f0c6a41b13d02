// Choosing a SIMD kernel by name, shared by the Hamming and L2 kernel
// families: the names, parsing, and the rule for an environment override (an
// unknown name, or a kernel this CPU cannot run, falls back to the best one
// with a warning).
#pragma once

#include <spdlog/spdlog.h>

#include <cstring>
#include <optional>
#include <string>

namespace placedb {
namespace internal {

// Kernel: an enum class with values 0 .. count - 1; `name` gives each one's
// name, `available` whether this CPU runs it.
template <typename Kernel>
std::optional<Kernel> KernelFromName(const char* requested, int count,
                                     const char* (*name)(Kernel)) {
  if (requested == nullptr) return std::nullopt;
  for (int k = 0; k < count; ++k) {
    const Kernel kernel = static_cast<Kernel>(k);
    if (std::strcmp(requested, name(kernel)) == 0) return kernel;
  }
  return std::nullopt;
}

template <typename Kernel>
Kernel ChooseKernel(const char* requested, const char* variable, int count, Kernel best,
                    const char* (*name)(Kernel), bool (*available)(Kernel)) {
  if (requested == nullptr || requested[0] == '\0') return best;
  const std::optional<Kernel> kernel = KernelFromName(requested, count, name);
  if (!kernel) {
    std::string known;
    for (int k = 0; k < count; ++k)
      known += (k ? "|" : "") + std::string(name(static_cast<Kernel>(k)));
    spdlog::warn("{}={}: unknown kernel ({}); using {}", variable, requested, known, name(best));
    return best;
  }
  if (!available(*kernel)) {
    spdlog::warn("{}={}: this CPU cannot run it; using {}", variable, requested, name(best));
    return best;
  }
  return *kernel;
}

}  // namespace internal
}  // namespace placedb
