// Internal helpers shared by the text-format readers of this module: reading
// the meaningful lines of a data file and parsing numbers with errors that name
// the data file and the line ("groundtruth.txt:12: expected 8 numbers, got 5").
#pragma once

#include <string>
#include <vector>

namespace placedb {
namespace internal {

// `text` with every byte outside printable ASCII written as \xNN, cut after
// `max_bytes` (error messages quote files, which may hold anything).
std::string Printable(const std::string& text, size_t max_bytes);

// One meaningful line of a text data file.
struct TextLine {
  int number = 0;    // 1-based line number in the file
  std::string text;  // the line without leading/trailing white space
};

// True when `path` names an existing regular file (symlinks followed).
bool IsRegularFile(const std::string& path);

// The lines of `path` that are neither blank nor comments ('#' as first
// non-blank character); handles CRLF line ends and a UTF-8 byte-order mark.
// A missing file throws NotFound (`what` describes the file's role, e.g.
// "ground-truth file"), a folder or a binary file InvalidArgument, an
// unreadable one IoError.
std::vector<TextLine> ReadDataLines(const std::string& path, const std::string& what);

// Splits `text` at any run of the characters in `separators`; no empty fields.
std::vector<std::string> SplitFields(const std::string& text, const std::string& separators);

// Throws InvalidArgument "<path>:<line>: <message>" (the data file's
// location; the source line is only in where(), as always).
[[noreturn]] void ThrowLineError(const std::string& path, int line, const std::string& message);

// Parse a whole token as a finite double / an int, or ThrowLineError naming
// the token and `what` (e.g. "timestamp").
double ParseDouble(const std::string& token, const std::string& path, int line,
                   const std::string& what);
int ParseInt(const std::string& token, const std::string& path, int line, const std::string& what);

}  // namespace internal
}  // namespace placedb
