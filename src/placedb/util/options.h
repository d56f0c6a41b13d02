// Range checks for options structs. Every option has a documented range and
// its struct's Check() tests it here, so the CLI, a manifest and a caller of
// the library get the same answer. The checks are NaN-safe (NaN is in no
// range) and name the field.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <string>

namespace placedb {

// "" when lo <= value <= hi (lo < value when lo_open), else
// "<name> must be in [lo, hi] (got value)".
std::string CheckRange(const std::string& name, double value, double lo, double hi,
                       bool lo_open = false);
std::string CheckRange(const std::string& name, int64_t value, int64_t lo, int64_t hi);
// The same for an int (so that int fields do not pick the double overload).
inline std::string CheckRange(const std::string& name, int value, int64_t lo, int64_t hi) {
  return CheckRange(name, static_cast<int64_t>(value), lo, hi);
}

// The first non-empty reason, or "".
std::string FirstReason(std::initializer_list<std::string> reasons);

// `reason` prefixed with "<prefix>." when not empty (nested options).
std::string Nested(const std::string& prefix, const std::string& reason);

}  // namespace placedb
