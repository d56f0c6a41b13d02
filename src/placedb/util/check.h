// Checks that throw. Library code never aborts or exits: it throws one of
// the errors of util/error.h, and only main() catches, printing one line and
// exiting with the error's code (cli/errors.h).
//
//   PLACEDB_CHECK(cond, ...)        an invariant of placedb's own code:
//                                   InternalError (a bug), with the condition
//   PLACEDB_THROW_INVALID(...)      bad input from the caller: InvalidArgument
//   PLACEDB_THROW_NOT_FOUND(...)    a file that does not exist: NotFound
//   PLACEDB_THROW_CORRUPT(...)      a damaged or foreign file: CorruptDatabase
//   PLACEDB_THROW_IO(...)           the system failed a read or write: IoError
//   PLACEDB_THROW_INTERNAL(...)     a bug found without a condition to test
//                                   (a tool of ours broke its contract)
//   PLACEDB_CHECK_OPTIONS(opts)     opts.Check() must be "": InvalidArgument
//
// The message is the streamed arguments (JoinMessage); the source line is
// kept in Error::where(), never in the message a user reads.
#pragma once

#include <sstream>
#include <string>

#include "placedb/util/error.h"

namespace placedb {
namespace internal {

// "util/check.cc:12": the path from the folder under placedb/ on.
std::string SourceLocation(const char* file, int line);

// Streams any number of values into a string: JoinMessage("a", 1, "b") = "a1b".
template <typename... Args>
std::string JoinMessage(const Args&... args) {
  std::ostringstream out;
  (out << ... << args);
  return out.str();
}

}  // namespace internal
}  // namespace placedb

#define PLACEDB_THROW_KIND_(Kind, ...)                                       \
  throw ::placedb::Kind(::placedb::internal::JoinMessage(__VA_ARGS__),       \
                        ::placedb::internal::SourceLocation(__FILE__, __LINE__))

// Throws InternalError unless `cond` holds; the message names the condition
// and any values streamed after it.
#define PLACEDB_CHECK(cond, ...)                                                         \
  do {                                                                                   \
    if (!(cond)) {                                                                       \
      PLACEDB_THROW_KIND_(InternalError, "check failed: " #cond " ", ##__VA_ARGS__);     \
    }                                                                                    \
  } while (false)

#define PLACEDB_THROW_INVALID(...) PLACEDB_THROW_KIND_(InvalidArgument, __VA_ARGS__)
#define PLACEDB_THROW_NOT_FOUND(...) PLACEDB_THROW_KIND_(NotFound, __VA_ARGS__)
#define PLACEDB_THROW_CORRUPT(...) PLACEDB_THROW_KIND_(CorruptDatabase, __VA_ARGS__)
#define PLACEDB_THROW_IO(...) PLACEDB_THROW_KIND_(IoError, __VA_ARGS__)
#define PLACEDB_THROW_INTERNAL(...) PLACEDB_THROW_KIND_(InternalError, __VA_ARGS__)

// Checks an options struct: `opts.Check()` returns "" when valid or the
// reason it is not (option names marked, `top_k`). The message names the
// options struct by its table's description ("invalid query options: ...").
#define PLACEDB_CHECK_OPTIONS(opts)                                                     \
  do {                                                                                  \
    const std::string placedb_reason_ = (opts).Check();                                 \
    if (!placedb_reason_.empty()) {                                                     \
      PLACEDB_THROW_INVALID("invalid ", ::placedb::internal::OptionsWhat(opts), ": ",   \
                            placedb_reason_);                                           \
    }                                                                                   \
  } while (false)

namespace placedb {
namespace internal {
// What an options struct is called in messages: its table's description
// when it has a table (Options::Table().what()), else "options".
template <typename T>
auto OptionsWhatImpl(const T& opts, int) -> decltype(T::Table().what()) {
  return T::Table().what();
}
template <typename T>
const char* OptionsWhatImpl(const T&, long) {
  return "options";
}
template <typename T>
std::string OptionsWhat(const T& opts) {
  return OptionsWhatImpl(opts, 0);
}
}  // namespace internal
}  // namespace placedb
