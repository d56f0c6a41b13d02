#include "placedb/util/option_table.h"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>

#include "placedb/util/check.h"

namespace placedb {

const char* OptionKindName(OptionKind kind) {
  switch (kind) {
    case OptionKind::kBool:
      return "bool";
    case OptionKind::kInt:
      return "int";
    case OptionKind::kUint64:
      return "uint64";
    case OptionKind::kDouble:
      return "double";
    case OptionKind::kText:
      return "text";
    case OptionKind::kChoice:
      return "choice";
    case OptionKind::kList:
      return "list";
    case OptionKind::kNumbers:
      return "numbers";
  }
  return "?";
}

// ---- ranges -----------------------------------------------------------------

OptionRange OptionRange::OneOf(std::vector<int64_t> values) {
  OptionRange r;
  r.one_of_ = std::move(values);
  return r;
}

bool OptionRange::Contains(double v) const {
  if (std::isnan(v)) return false;
  if (!one_of_.empty()) {
    return std::any_of(one_of_.begin(), one_of_.end(),
                       [v](int64_t x) { return static_cast<double>(x) == v; });
  }
  if (!interval_) return true;
  return (lo_open_ ? v > lo_ : v >= lo_) && (hi_open_ ? v < hi_ : v <= hi_);
}

namespace option_table_internal {

// Whole numbers in a short exact form: 2^31 for large powers of two, 1e6
// for powers of ten from a million on; others as they are.
std::string FormatNumber(double v) {
  if (std::isfinite(v) && v == std::floor(v) && std::fabs(v) >= 65536.0) {
    const double a = std::fabs(v);
    const int e2 = static_cast<int>(std::lround(std::log2(a)));
    if (std::ldexp(1.0, e2) == a) return fmt::format("{}2^{}", v < 0 ? "-" : "", e2);
    const int e10 = static_cast<int>(std::lround(std::log10(a)));
    if (e10 >= 6 && std::pow(10.0, e10) == a) return fmt::format("{}1e{}", v < 0 ? "-" : "", e10);
  }
  if (std::isfinite(v) && v == std::floor(v) && std::fabs(v) < 9.2e18) {
    return std::to_string(static_cast<int64_t>(v));
  }
  return fmt::format("{}", v);
}

std::string FormatValue(double v) { return fmt::format("{}", v); }

std::string OutOfRange(const std::string& name, const std::string& range, const std::string& got) {
  return "`" + name + "` must be " + (range.find_first_of("[(") == 0 ? "in " : "") + range +
         " (got " + got + ")";
}

namespace {
[[noreturn]] void WrongKind(const std::string& name, const char* wanted, const OptionValue& v) {
  static const char* const kHeld[] = {"a bool",   "a whole number", "a whole number",   "a number",
                                      "a string", "a list",         "a list of numbers"};
  PLACEDB_THROW_INVALID("`", name, "` takes ", wanted, ", not ", kHeld[v.index()]);
}
}  // namespace

int64_t ToInt64(const OptionValue& v, const std::string& name, int64_t lo, int64_t hi,
                const std::string& range) {
  if (const int64_t* i = std::get_if<int64_t>(&v)) {
    if (*i < lo || *i > hi) PLACEDB_THROW_INVALID(OutOfRange(name, range, std::to_string(*i)));
    return *i;
  }
  if (const uint64_t* u = std::get_if<uint64_t>(&v)) {
    if (*u > static_cast<uint64_t>(hi)) {
      PLACEDB_THROW_INVALID(OutOfRange(name, range, std::to_string(*u)));
    }
    return static_cast<int64_t>(*u);
  }
  WrongKind(name, "a whole number", v);
}

uint64_t ToUint64(const OptionValue& v, const std::string& name) {
  if (const uint64_t* u = std::get_if<uint64_t>(&v)) return *u;
  if (const int64_t* i = std::get_if<int64_t>(&v)) {
    if (*i < 0) {
      PLACEDB_THROW_INVALID(OutOfRange(name, "[0, 2^64)", std::to_string(*i)));
    }
    return static_cast<uint64_t>(*i);
  }
  WrongKind(name, "a whole number", v);
}

double ToDouble(const OptionValue& v, const std::string& name) {
  if (const double* d = std::get_if<double>(&v)) return *d;
  if (const int64_t* i = std::get_if<int64_t>(&v)) return static_cast<double>(*i);
  if (const uint64_t* u = std::get_if<uint64_t>(&v)) return static_cast<double>(*u);
  WrongKind(name, "a number", v);
}

bool ToBool(const OptionValue& v, const std::string& name) {
  if (const bool* b = std::get_if<bool>(&v)) return *b;
  WrongKind(name, "true or false", v);
}

std::string ToString(const OptionValue& v, const std::string& name) {
  if (const std::string* s = std::get_if<std::string>(&v)) return *s;
  WrongKind(name, "a string", v);
}

std::vector<std::string> ToList(const OptionValue& v, const std::string& name) {
  if (const auto* l = std::get_if<std::vector<std::string>>(&v)) return *l;
  if (const auto* n = std::get_if<std::vector<double>>(&v)) {
    // Numbers from a typed client: the same text a command line gives.
    std::vector<std::string> items;
    for (const double x : *n) items.push_back(fmt::format("{}", x));
    return items;
  }
  if (const std::string* s = std::get_if<std::string>(&v)) return {*s};
  WrongKind(name, "a list", v);
}

std::vector<double> ToNumbers(const OptionValue& v, const std::string& name) {
  if (const auto* l = std::get_if<std::vector<double>>(&v)) return *l;
  WrongKind(name, "a list of numbers", v);
}

}  // namespace option_table_internal

namespace oi = option_table_internal;

std::string OptionRange::Text() const {
  if (!one_of_.empty()) {
    std::string out;
    for (size_t i = 0; i < one_of_.size(); ++i) {
      out += (i == 0 ? "" : i + 1 == one_of_.size() ? " or " : ", ") + std::to_string(one_of_[i]);
    }
    return out;
  }
  if (!interval_) return "any";
  return fmt::format("{}{}, {}{}", lo_open_ ? "(" : "[", oi::FormatNumber(lo_),
                     oi::FormatNumber(hi_), hi_open_ ? ")" : "]");
}

// ---- tables -----------------------------------------------------------------

void OptionTableBase::AddEntry(Entry entry) {
  OptionField& f = entry.field;
  PLACEDB_CHECK(!f.name.empty() && Find(f.name) == nullptr, "option ", f.name, " in ", what_);
  if (f.flag.empty()) {
    std::string dashed = f.name;
    std::replace(dashed.begin(), dashed.end(), '_', '-');
    f.flag = f.kind == OptionKind::kBool && f.bool_flag == BoolFlag::kNegatable
                 ? "--" + dashed + ",!--no-" + dashed
                 : "--" + dashed;
  }
  entries_.push_back(std::move(entry));
}

const OptionTableBase::Entry* OptionTableBase::Find(const std::string& name) const {
  for (const Entry& e : entries_) {
    if (e.field.name == name) return &e;
  }
  return nullptr;
}

namespace {
const OptionTableBase::Entry& Required(const OptionTableBase& table, const std::string& name) {
  const OptionTableBase::Entry* e = table.Find(name);
  if (e == nullptr) {
    std::string known;
    for (const auto& x : table.entries()) known += (known.empty() ? "" : ", ") + x.field.name;
    PLACEDB_THROW_INVALID("unknown ", table.what(), " option '", name, "' (", table.what(),
                          " are: ", known, ")");
  }
  return *e;
}

// The items of a comma-separated list ("" is no item).
std::vector<std::string> SplitList(const std::string& text) {
  std::vector<std::string> items;
  if (text.empty()) return items;
  size_t begin = 0;
  while (true) {
    const size_t comma = text.find(',', begin);
    items.push_back(text.substr(begin, comma == std::string::npos ? comma : comma - begin));
    if (comma == std::string::npos) break;
    begin = comma + 1;
  }
  return items;
}

bool ParseDouble(const std::string& text, double* out) {
  if (text.empty() || std::isspace(static_cast<unsigned char>(text[0]))) return false;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size()) return false;
  // ERANGE is an overflow (±HUGE_VAL: refused) or an underflow (a subnormal
  // or 0, such as 1e-320: a number all the same, which the range checks).
  if (errno == ERANGE && std::isinf(v)) return false;
  *out = v;
  return true;
}
}  // namespace

OptionValue OptionTableBase::Get(const void* options, const std::string& name) const {
  return Required(*this, name).get(options);
}

void OptionTableBase::Set(void* options, const std::string& name, const OptionValue& value) const {
  Required(*this, name).set(options, value);
}

void OptionTableBase::SetText(void* options, const std::string& name,
                              const std::string& text) const {
  const Entry& e = Required(*this, name);
  const std::string& n = e.field.name;
  switch (e.field.kind) {
    case OptionKind::kBool: {
      static const char* const kTrue[] = {"true", "1", "yes", "on"};
      static const char* const kFalse[] = {"false", "0", "no", "off"};
      for (const char* t : kTrue) {
        if (text == t) return e.set(options, true);
      }
      for (const char* f : kFalse) {
        if (text == f) return e.set(options, false);
      }
      PLACEDB_THROW_INVALID("`", n, "` takes true or false (got '", text, "')");
    }
    case OptionKind::kInt: {
      // Whole numbers only, in full: "12", "-3"; not "1.5", "12x", " 3".
      const bool digits = !text.empty() &&
                          std::all_of(text.begin() + (text[0] == '-' ? 1 : 0), text.end(),
                                      [](char c) { return c >= '0' && c <= '9'; }) &&
                          text != "-";
      if (!digits) {
        PLACEDB_THROW_INVALID("`", n, "` takes a whole number in ", e.field.range, " (got '", text,
                              "')");
      }
      errno = 0;
      const long long v = std::strtoll(text.c_str(), nullptr, 10);
      if (errno == ERANGE) PLACEDB_THROW_INVALID(oi::OutOfRange(n, e.field.range, text));
      return e.set(options, static_cast<int64_t>(v));
    }
    case OptionKind::kUint64: {
      const bool digits = !text.empty() && std::all_of(text.begin(), text.end(),
                                                       [](char c) { return c >= '0' && c <= '9'; });
      if (!digits) {
        PLACEDB_THROW_INVALID("`", n, "` takes a whole number in [0, 2^64) (got '", text, "')");
      }
      errno = 0;
      const unsigned long long v = std::strtoull(text.c_str(), nullptr, 10);
      if (errno == ERANGE) PLACEDB_THROW_INVALID(oi::OutOfRange(n, "[0, 2^64)", text));
      return e.set(options, static_cast<uint64_t>(v));
    }
    case OptionKind::kDouble: {
      double v = 0.0;
      if (!ParseDouble(text, &v)) {
        PLACEDB_THROW_INVALID("`", n, "` takes a number in ", e.field.range, " (got '", text, "')");
      }
      return e.set(options, v);
    }
    case OptionKind::kText:
    case OptionKind::kChoice:
      return e.set(options, text);
    case OptionKind::kList:
      return e.set(options, SplitList(text));
    case OptionKind::kNumbers: {
      std::vector<double> numbers;
      for (const std::string& item : SplitList(text)) {
        double v = 0.0;
        if (!ParseDouble(item, &v)) {
          PLACEDB_THROW_INVALID("`", n, "` takes comma-separated numbers (got '", text, "')");
        }
        numbers.push_back(v);
      }
      return e.set(options, numbers);
    }
  }
}

std::string OptionTableBase::Text(const OptionValue& value) {
  struct Visitor {
    std::string operator()(bool b) const { return b ? "true" : "false"; }
    std::string operator()(int64_t i) const { return std::to_string(i); }
    std::string operator()(uint64_t u) const { return std::to_string(u); }
    std::string operator()(double d) const { return fmt::format("{}", d); }
    std::string operator()(const std::string& s) const { return s; }
    std::string operator()(const std::vector<std::string>& l) const {
      std::string out;
      for (size_t i = 0; i < l.size(); ++i) out += (i == 0 ? "" : ",") + l[i];
      return out;
    }
    std::string operator()(const std::vector<double>& l) const {
      std::string out;
      for (size_t i = 0; i < l.size(); ++i) out += fmt::format("{}{}", i == 0 ? "" : ",", l[i]);
      return out;
    }
  };
  return std::visit(Visitor(), value);
}

std::string OptionTableBase::CheckAll(const void* options) const {
  for (const Entry& e : entries_) {
    std::string reason = e.check(options);
    if (!reason.empty()) return reason;
  }
  return CheckRules(options);
}

std::string OptionTableBase::CheckLayout() const {
  std::vector<Placed> placed = layout_;
  std::sort(placed.begin(), placed.end(),
            [](const Placed& a, const Placed& b) { return a.offset < b.offset; });
  auto round_up = [](size_t n, size_t align) { return (n + align - 1) / align * align; };
  size_t end = 0;
  for (const Placed& p : placed) {
    if (p.offset > round_up(end, p.align)) {
      return fmt::format(
          "{}: bytes [{}, {}) of the struct are no option's member (a member "
          "missing from the table?)",
          what_, end, p.offset);
    }
    end = std::max(end, p.offset + p.bytes);
  }
  if (round_up(end, struct_align_) != struct_bytes_) {
    return fmt::format(
        "{}: the options' members end at byte {} of a {}-byte struct (a member "
        "missing from the table?)",
        what_, end, struct_bytes_);
  }
  return "";
}

std::string OptionTableBase::CheckRules(const void* options) const {
  for (const auto& rule : rules_) {
    std::string reason = rule(options);
    if (!reason.empty()) return reason;
  }
  return "";
}

}  // namespace placedb
