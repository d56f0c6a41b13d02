#include "placedb/util/options.h"

#include <fmt/format.h>

namespace placedb {

std::string CheckRange(const std::string& name, double value, double lo, double hi, bool lo_open) {
  const bool ok = (lo_open ? value > lo : value >= lo) && value <= hi;  // false for NaN
  if (ok) return "";
  return fmt::format("{} must be in {}{}, {}] (got {})", name, lo_open ? "(" : "[", lo, hi, value);
}

std::string CheckRange(const std::string& name, int64_t value, int64_t lo, int64_t hi) {
  if (value >= lo && value <= hi) return "";
  return fmt::format("{} must be in [{}, {}] (got {})", name, lo, hi, value);
}

std::string FirstReason(std::initializer_list<std::string> reasons) {
  for (const std::string& r : reasons) {
    if (!r.empty()) return r;
  }
  return "";
}

std::string Nested(const std::string& prefix, const std::string& reason) {
  return reason.empty() ? reason : prefix + "." + reason;
}

}  // namespace placedb
