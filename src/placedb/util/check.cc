#include "placedb/util/check.h"

#include <cstring>

namespace placedb {
namespace internal {

std::string SourceLocation(const char* file, int line) {
  // Keep the path from "placedb/" on: short and still unambiguous.
  const char* shown = std::strstr(file, "src/placedb/");
  shown = shown != nullptr ? shown + std::strlen("src/placedb/") : file;
  return std::string(shown) + ":" + std::to_string(line);
}

}  // namespace internal
}  // namespace placedb
