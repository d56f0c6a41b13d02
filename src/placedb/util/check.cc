#include "placedb/util/check.h"

#include <cstring>

namespace placedb {
namespace internal {

std::string FormatCheckMessage(const char* file, int line, const std::string& message) {
  // Keep the path from "placedb/" on: short and still unambiguous.
  const char* shown = std::strstr(file, "placedb/");
  return std::string(shown != nullptr ? shown : file) + ":" + std::to_string(line) + ": " + message;
}

}  // namespace internal
}  // namespace placedb
