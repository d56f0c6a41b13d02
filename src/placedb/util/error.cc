#include "placedb/util/error.h"

#include <cctype>
#include <utility>

namespace placedb {

const char* ErrorKindName(ErrorKind kind) {
  switch (kind) {
    case ErrorKind::kInvalidArgument:
      return "invalid argument";
    case ErrorKind::kNotFound:
      return "not found";
    case ErrorKind::kCorruptDatabase:
      return "corrupt database";
    case ErrorKind::kIo:
      return "I/O error";
    case ErrorKind::kInternal:
      return "internal error";
  }
  return "error";
}

Error::Error(ErrorKind kind, std::string message, std::string where)
    : kind_(kind), message_(std::move(message)), where_(std::move(where)) {
  what_ = FormatOptionNames(message_, OptionNames::kKeywords);
  if (kind_ == ErrorKind::kInternal) {
    what_ = "internal error (a bug in placedb; please report it): " + what_;
    if (!where_.empty()) what_ += " [" + where_ + "]";
  }
}

std::string FormatOptionNames(const std::string& text, OptionNames style) {
  return FormatOptionNames(text, [style](const std::string& name) {
    if (style == OptionNames::kKeywords) return name;
    std::string flag = "--" + name;
    for (char& c : flag) {
      if (c == '_') c = '-';
    }
    return flag;
  });
}

std::string FormatOptionNames(const std::string& text,
                              const std::function<std::string(const std::string&)>& write) {
  std::string out;
  out.reserve(text.size() + 8);
  size_t i = 0;
  while (i < text.size()) {
    if (text[i] == '`') {
      size_t end = i + 1;
      while (end < text.size() &&
             (std::islower(static_cast<unsigned char>(text[end])) ||
              std::isdigit(static_cast<unsigned char>(text[end])) || text[end] == '_')) {
        ++end;
      }
      if (end < text.size() && text[end] == '`' && end > i + 1 &&
          std::islower(static_cast<unsigned char>(text[i + 1]))) {
        out += write(text.substr(i + 1, end - i - 1));
        i = end + 1;
        continue;
      }
    }
    out += text[i++];
  }
  return out;
}

}  // namespace placedb
