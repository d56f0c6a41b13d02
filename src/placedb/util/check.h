// Checks that throw. Library code never aborts or exits: a failed check throws
// std::invalid_argument (bad input from the caller) or std::runtime_error
// (environment: files, formats), with file:line and a readable message. Only
// main() catches and turns it into one line and a non-zero exit code.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace placedb {
namespace internal {

// Builds "file:line: message" for the exception text.
std::string FormatCheckMessage(const char* file, int line, const std::string& message);

// Streams any number of values into a string: JoinMessage("a", 1, "b") = "a1b".
template <typename... Args>
std::string JoinMessage(const Args&... args) {
  std::ostringstream out;
  (out << ... << args);
  return out.str();
}

}  // namespace internal
}  // namespace placedb

// Throws std::invalid_argument unless `cond` holds; the message names the
// condition and any extra values streamed after it.
#define PLACEDB_CHECK(cond, ...)                                                         \
  do {                                                                                   \
    if (!(cond)) {                                                                       \
      throw std::invalid_argument(::placedb::internal::FormatCheckMessage(               \
          __FILE__, __LINE__,                                                            \
          ::placedb::internal::JoinMessage("check failed: " #cond " ", ##__VA_ARGS__))); \
    }                                                                                    \
  } while (false)

// Throws std::runtime_error with the streamed message (I/O and format errors).
#define PLACEDB_THROW_RUNTIME(...)                                  \
  throw std::runtime_error(::placedb::internal::FormatCheckMessage( \
      __FILE__, __LINE__, ::placedb::internal::JoinMessage(__VA_ARGS__)))

// Throws std::invalid_argument with the streamed message (bad user input).
#define PLACEDB_THROW_INVALID(...)                                     \
  throw std::invalid_argument(::placedb::internal::FormatCheckMessage( \
      __FILE__, __LINE__, ::placedb::internal::JoinMessage(__VA_ARGS__)))

// Checks an options struct: `opts.Check()` returns an empty string when valid
// or the reason it is not.
#define PLACEDB_CHECK_OPTIONS(opts)                                  \
  do {                                                               \
    const std::string placedb_reason_ = (opts).Check();              \
    if (!placedb_reason_.empty()) {                                  \
      PLACEDB_THROW_INVALID("invalid " #opts ": ", placedb_reason_); \
    }                                                                \
  } while (false)
