// The errors placedb throws: one small hierarchy, so that a caller can tell
// bad input from a missing file, a damaged database, a failing system and a
// bug in placedb.
//
//   placedb::Error        every error of the library (a std::exception)
//     InvalidArgument     a bad value from the caller: an option out of its
//                         range, features of another type, an unknown
//                         keyframe id, an image that is not a frame
//     NotFound            a file or folder that does not exist: a database,
//                         an image, a list, a ground-truth file
//     CorruptDatabase     a database, index or vocabulary file (or a
//                         manifest) that is damaged, truncated, of another
//                         version or not placedb's
//     IoError             the system failed a read or a write: permissions,
//                         a full disk, an unreadable device
//     InternalError       a broken invariant: a bug in placedb
//
// what() is a message for the user. It names options by their public name,
// the one of the option tables (the Python keyword; the CLI flag is the same
// with dashes: top_k, --top-k), and never a source file or a variable; only
// an InternalError's what() names the source line, which every error keeps
// in where() for debug logs (`placedb --verbose`).
//
// In message(), option names are marked with backquotes (`top_k`), so that
// a client can write them its own way (FormatOptionNames): the CLI as flags,
// Python as keywords.
#pragma once

#include <exception>
#include <functional>
#include <string>

namespace placedb {

enum class ErrorKind { kInvalidArgument, kNotFound, kCorruptDatabase, kIo, kInternal };
// "invalid argument", "not found", "corrupt database", "I/O error", "internal error".
const char* ErrorKindName(ErrorKind kind);

class Error : public std::exception {
 public:
  // `where`: the throw's source location ("session/place_database.cc:120"),
  // or "".
  Error(ErrorKind kind, std::string message, std::string where = "");

  ErrorKind kind() const { return kind_; }
  // The message with option names marked (`top_k`).
  const std::string& message() const { return message_; }
  // Where it was thrown, for debug logs; "" when unknown.
  const std::string& where() const { return where_; }
  // The message with option names as keywords; an InternalError's also
  // names where().
  const char* what() const noexcept override { return what_.c_str(); }

 private:
  ErrorKind kind_;
  std::string message_;
  std::string where_;
  std::string what_;
};

class InvalidArgument : public Error {
 public:
  explicit InvalidArgument(std::string message, std::string where = "")
      : Error(ErrorKind::kInvalidArgument, std::move(message), std::move(where)) {}
};

class NotFound : public Error {
 public:
  explicit NotFound(std::string message, std::string where = "")
      : Error(ErrorKind::kNotFound, std::move(message), std::move(where)) {}
};

class CorruptDatabase : public Error {
 public:
  explicit CorruptDatabase(std::string message, std::string where = "")
      : Error(ErrorKind::kCorruptDatabase, std::move(message), std::move(where)) {}
};

class IoError : public Error {
 public:
  explicit IoError(std::string message, std::string where = "")
      : Error(ErrorKind::kIo, std::move(message), std::move(where)) {}
};

class InternalError : public Error {
 public:
  explicit InternalError(std::string message, std::string where = "")
      : Error(ErrorKind::kInternal, std::move(message), std::move(where)) {}
};

// How a client writes option names.
enum class OptionNames {
  kKeywords,  // top_k (Python, C++)
  kFlags,     // --top-k (the command line)
};
// `text` with every backquoted option name (`top_k`: lower-case letters,
// digits and underscores) written in `style`; other text is left as it is.
std::string FormatOptionNames(const std::string& text, OptionNames style);
// The same with each name written by `write` (a client that spells some
// flags its own way: the CLI's --no-images for store_images).
std::string FormatOptionNames(const std::string& text,
                              const std::function<std::string(const std::string&)>& write);

}  // namespace placedb
