#include "placedb/dataset/text_lines.h"

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <system_error>

#include "placedb/util/check.h"
#include "placedb/util/file_io.h"

namespace placedb {
namespace internal {
namespace {

constexpr const char* kBlanks = " \t\r\n\f\v";

std::string Trim(const std::string& s) {
  const size_t begin = s.find_first_not_of(kBlanks);
  if (begin == std::string::npos) return "";
  const size_t end = s.find_last_not_of(kBlanks);
  return s.substr(begin, end - begin + 1);
}

// from_chars does not take a leading '+'; accept it like strtod does.
const char* SkipPlus(const std::string& token) {
  const char* p = token.data();
  if (token.size() > 1 && p[0] == '+' && p[1] != '-' && p[1] != '+') ++p;
  return p;
}

}  // namespace

bool IsRegularFile(const std::string& path) {
  std::error_code ec;
  return std::filesystem::is_regular_file(path, ec);
}

std::vector<TextLine> ReadDataLines(const std::string& path, const std::string& what) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) PLACEDB_THROW_NOT_FOUND(what, " not found: ", path);
  if (std::filesystem::is_directory(path, ec)) {
    PLACEDB_THROW_INVALID(what, " is a directory, expected a text file: ", path);
  }
  std::string content = ReadFileToString(path);  // IoError when unreadable
  if (content.compare(0, 3, "\xEF\xBB\xBF") == 0) content.erase(0, 3);
  if (content.find('\0') != std::string::npos) {
    PLACEDB_THROW_INVALID(what, " ", path, " is not a text file (it holds NUL bytes)");
  }

  std::vector<TextLine> lines;
  int number = 0;
  size_t pos = 0;
  while (pos < content.size()) {
    size_t end = content.find('\n', pos);
    if (end == std::string::npos) end = content.size();
    ++number;
    std::string text = Trim(content.substr(pos, end - pos));
    if (!text.empty() && text[0] != '#') lines.push_back({number, std::move(text)});
    pos = end + 1;
  }
  return lines;
}

std::vector<std::string> SplitFields(const std::string& text, const std::string& separators) {
  std::vector<std::string> fields;
  size_t pos = text.find_first_not_of(separators);
  while (pos != std::string::npos) {
    const size_t end = text.find_first_of(separators, pos);
    fields.push_back(text.substr(pos, end == std::string::npos ? std::string::npos : end - pos));
    pos = text.find_first_not_of(separators, end);
  }
  return fields;
}

std::string Printable(const std::string& text, size_t max_bytes) {
  static const char kHex[] = "0123456789abcdef";
  std::string out;
  for (size_t i = 0; i < text.size(); ++i) {
    if (out.size() >= max_bytes) {
      out += "...";
      break;
    }
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c >= 0x20 && c < 0x7f) {
      out += static_cast<char>(c);
    } else {
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 15];
    }
  }
  return out;
}

void ThrowLineError(const std::string& path, int line, const std::string& message) {
  // The data file's location is the useful one here, not this helper's. The
  // message quotes the file, which may hold anything: only printable bytes.
  PLACEDB_THROW_INVALID(path, ":", line, ": ", Printable(message, 300));
}

double ParseDouble(const std::string& token, const std::string& path, int line,
                   const std::string& what) {
  const char* begin = SkipPlus(token);
  const char* end = token.data() + token.size();
  double value = 0.0;
  auto [ptr, ec] = std::from_chars(begin, end, value, std::chars_format::general);
  if (ec == std::errc::result_out_of_range && ptr == end) {
    // An underflow (1e-320: a subnormal or 0) is a number; an overflow is not.
    value = std::strtod(std::string(begin, end).c_str(), nullptr);
    if (std::isfinite(value)) ec = std::errc();
  }
  if (ec != std::errc() || ptr != end || !std::isfinite(value)) {
    ThrowLineError(path, line, "expected a number for " + what + ", got '" + token + "'");
  }
  return value;
}

int ParseInt(const std::string& token, const std::string& path, int line, const std::string& what) {
  const char* begin = SkipPlus(token);
  const char* end = token.data() + token.size();
  int value = 0;
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  if (ec != std::errc() || ptr != end) {
    ThrowLineError(path, line, "expected an integer for " + what + ", got '" + token + "'");
  }
  return value;
}

}  // namespace internal
}  // namespace placedb
