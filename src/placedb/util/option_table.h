// Option tables: every options struct of placedb is described once, by a
// table of its options (public name, member, default, range, help), and
// everything else is made from that table:
//   - the struct's Check() (ranges, NaN-safe; the struct adds rules between
//     options),
//   - the command line's flags and their help (cli/options.h),
//   - the Python module's keyword arguments and their docs,
//   - the manifest's settings, written and read back strictly (a key that is
//     missing or unknown is an error naming it; util/option_json.h),
//   - the README's table of option ranges (`placedb options --markdown`).
//
// An option's public name is its Python keyword; its command-line flag is
// the same with dashes (top_k, --top-k) unless the table gives another
// spelling. Messages name options by it, marked with backquotes (`top_k`),
// so that each client writes them its own way (util/error.h).
//
// A struct with a table declares `static const OptionTable<X>& Table();` and
// defines it beside its Check():
//
//   const OptionTable<OrbOptions>& OrbOptions::Table() {
//     static const OptionTable<OrbOptions> table = [] {
//       OptionTable<OrbOptions> t("ORB options");
//       t.Number("orb_max_features", PLACEDB_MEMBER(OrbOptions, max_features),
//                OptionRange::Closed(1, 100000), "ORB: most keypoints per image");
//       ...
//       return t;
//     }();
//     return table;
//   }
//   std::string OrbOptions::Check() const { return Table().Check(*this); }
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <initializer_list>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>
#include <vector>

#include "placedb/util/error.h"

namespace placedb {

// What an option holds.
enum class OptionKind {
  kBool,
  kInt,      // a whole number (an int or int64_t member)
  kUint64,   // a whole number in [0, 2^64) (seeds)
  kDouble,   // a real number
  kText,     // a path or a name
  kChoice,   // one of a few names (an enum member)
  kList,     // a list of names or numbers ("orb,surf", "1,4,16")
  kNumbers,  // a list of numbers, or none (a pose: x, y, z, qx, qy, qz, qw)
};
// "bool", "int", "uint64", "double", "text", "choice", "list", "numbers".
const char* OptionKindName(OptionKind kind);

// A value given to an option, by a client that has types (Python, JSON) or
// as text (a command line: OptionTableBase::SetText).
using OptionValue = std::variant<bool, int64_t, uint64_t, double, std::string,
                                 std::vector<std::string>, std::vector<double>>;

// Where an option appears besides Check(): a bit set.
enum OptionSurface : unsigned {
  kCommandLine = 1u,  // a flag of the commands that take the struct
  kPython = 2u,       // a keyword of the Python functions that take it
  kManifest = 4u,     // a key of a database's manifest (build settings)
  kEverywhere = kCommandLine | kPython | kManifest,
  kCallers = kCommandLine | kPython,  // not stored: run-time settings
};

// How a bool option is spelled on the command line.
enum class BoolFlag {
  kValue,      // --name true|false
  kSwitch,     // --name sets true (the default is false)
  kNegatable,  // --name sets true, --no-name false
  kInverted,   // only the flag the table spells (e.g. --no-images) sets false
};

// The values an option may take.
class OptionRange {
 public:
  // Any value of the member's type.
  static OptionRange Any() { return OptionRange(); }
  // [lo, hi]; LeftOpen (lo, hi]; RightOpen [lo, hi).
  static OptionRange Closed(double lo, double hi) { return {lo, hi, false, false}; }
  static OptionRange LeftOpen(double lo, double hi) { return {lo, hi, true, false}; }
  static OptionRange RightOpen(double lo, double hi) { return {lo, hi, false, true}; }
  // One of these whole numbers ("1, 4 or 16").
  static OptionRange OneOf(std::vector<int64_t> values);

  bool any() const { return !interval_ && one_of_.empty(); }
  // An interval's bounds (interval() false: any value, or OneOf).
  bool interval() const { return interval_; }
  double lo() const { return lo_; }
  double hi() const { return hi_; }
  bool lo_open() const { return lo_open_; }
  bool hi_open() const { return hi_open_; }
  const std::vector<int64_t>& one_of() const { return one_of_; }
  // Whether `v` is in it (NaN never is).
  bool Contains(double v) const;
  // "[1, 10000]", "(0, 1]", "[0, 2^31)", "1, 4 or 16", "any".
  std::string Text() const;

 private:
  OptionRange() = default;
  OptionRange(double lo, double hi, bool lo_open, bool hi_open)
      : interval_(true), lo_(lo), hi_(hi), lo_open_(lo_open), hi_open_(hi_open) {}
  bool interval_ = false;
  double lo_ = 0.0, hi_ = 0.0;
  bool lo_open_ = false, hi_open_ = false;
  std::vector<int64_t> one_of_;
};

// The description of one option, as clients see it.
struct OptionField {
  std::string name;     // public name: the Python keyword
  std::string flag;     // the command-line flag(s) as CLI11 spells them:
                        // "--top-k", "--verify,!--no-verify", "--no-images"
  std::string member;   // the C++ member, from the table's struct: "verify.num_candidates"
  OptionKind kind = OptionKind::kInt;
  std::string help;     // one line
  std::string range;    // the range's text, or the choices: "orb or surf"
  OptionRange bounds = OptionRange::Any();  // a number's range
  std::string default_text;  // the struct's default, as text
  std::vector<std::string> choices;  // kChoice, kList of names: the names
  unsigned surfaces = kEverywhere;
  BoolFlag bool_flag = BoolFlag::kValue;
  // kManifest: the value a manifest written before the option existed
  // means when it lacks the key; none: the key is required.
  std::optional<OptionValue> absent;
};

// What every table has, whatever its struct: the fields and untyped access
// (a void* is the struct). OptionTable<T> below is the typed face.
class OptionTableBase {
 public:
  struct Entry {
    OptionField field;
    std::function<OptionValue(const void*)> get;
    // Throws InvalidArgument naming the option for a value of another kind
    // or outside the member's type (an int option given 2^40).
    std::function<void(void*, const OptionValue&)> set;
    // "" or the reason the value is outside the range.
    std::function<std::string(const void*)> check;
  };

  OptionTableBase(std::string what, size_t struct_bytes, size_t struct_align)
      : what_(std::move(what)), struct_bytes_(struct_bytes), struct_align_(struct_align) {}
  // "query options", "build settings": what messages call the struct.
  const char* what() const { return what_.c_str(); }
  const std::vector<Entry>& entries() const { return entries_; }
  // The entry named `name`, or nullptr.
  const Entry* Find(const std::string& name) const;

  // The value of option `name` (InvalidArgument for an unknown name).
  OptionValue Get(const void* options, const std::string& name) const;
  void Set(void* options, const std::string& name, const OptionValue& value) const;
  // Sets option `name` from text, as a command line gives it: a bool from
  // true/false (also 1/0, yes/no, on/off), numbers in full (no trailing
  // characters), a choice by its name, a list and numbers comma-separated.
  void SetText(void* options, const std::string& name, const std::string& text) const;
  // The value as text (the form SetText reads).
  static std::string Text(const OptionValue& value);
  // The first option outside its range, then the struct's rules; "".
  std::string CheckAll(const void* options) const;
  // The rules between options alone (nested structs' included).
  std::string CheckRules(const void* options) const;
  // Whether the table describes every member of its struct: the members
  // its options set, laid out by offset, must fill the struct but for the
  // padding the members' alignment makes ("" when they do, else where the
  // gap is). A member added to the struct and forgotten in the table leaves
  // a gap. (A nested struct counts whole; its own table checks inside it.)
  std::string CheckLayout() const;

 protected:
  void AddEntry(Entry entry);
  // Bytes [offset, offset + bytes) of the struct are an option's member.
  struct Placed {
    size_t offset, bytes, align;
  };
  void Place(Placed placed) { layout_.push_back(placed); }
  void AddRule(std::function<std::string(const void*)> rule) { rules_.push_back(std::move(rule)); }
  std::string what_;
  size_t struct_bytes_, struct_align_;
  std::vector<Placed> layout_;
  std::vector<Entry> entries_;
  std::vector<std::function<std::string(const void*)>> rules_;
};

namespace option_table_internal {
template <typename T>
struct IsVector : std::false_type {};
template <typename T>
struct IsVector<std::vector<T>> : std::true_type {};
// Whole numbers of an OptionValue, refusing other kinds and values outside
// [lo, hi]; they throw InvalidArgument naming `name`.
int64_t ToInt64(const OptionValue& v, const std::string& name, int64_t lo, int64_t hi,
                const std::string& range);
uint64_t ToUint64(const OptionValue& v, const std::string& name);
double ToDouble(const OptionValue& v, const std::string& name);
bool ToBool(const OptionValue& v, const std::string& name);
std::string ToString(const OptionValue& v, const std::string& name);
std::vector<std::string> ToList(const OptionValue& v, const std::string& name);
std::vector<double> ToNumbers(const OptionValue& v, const std::string& name);
// "`name` must be in <range> (got <value>)".
std::string OutOfRange(const std::string& name, const std::string& range, const std::string& got);
std::string FormatNumber(double v);
// A value as given, in the shortest form that reads back: 1000000, 0.8, nan.
std::string FormatValue(double v);
}  // namespace option_table_internal

// A member of struct T and its name, for the table: PLACEDB_MEMBER(T, top_k).
#define PLACEDB_MEMBER(T, member) &T::member, #member

template <typename T>
class OptionTable : public OptionTableBase {
 public:
  explicit OptionTable(std::string what)
      : OptionTableBase(std::move(what), sizeof(T), alignof(T)) {}

  // A bool, whole or real number member.
  template <typename M>
  OptionField& Number(const std::string& name, M T::*member, const char* member_name,
                      OptionRange range, const std::string& help,
                      unsigned surfaces = kEverywhere);
  OptionField& Bool(const std::string& name, bool T::*member, const char* member_name,
                    const std::string& help, BoolFlag flag = BoolFlag::kValue,
                    unsigned surfaces = kEverywhere);
  OptionField& String(const std::string& name, std::string T::*member, const char* member_name,
                    const std::string& help, unsigned surfaces = kEverywhere);
  // An enum member, named by `to_name` and parsed by `parse` (which throws
  // InvalidArgument for an unknown name).
  template <typename E, typename Parse, typename Name>
  OptionField& Choice(const std::string& name, E T::*member, const char* member_name,
                      std::vector<E> values, Parse parse, Name to_name, const std::string& help,
                      unsigned surfaces = kEverywhere);
  // A list member: its items are `values` (named by `to_name`, parsed from
  // a name by `parse`), and the list must be non-empty without repeats.
  template <typename E, typename Parse, typename Name>
  OptionField& List(const std::string& name, std::vector<E> T::*member, const char* member_name,
                    std::vector<E> values, Parse parse, Name to_name, const std::string& help,
                    unsigned surfaces = kEverywhere);
  // Any other value: its kind, and how to get and set it (`set` throws
  // InvalidArgument naming the option; `check` returns a reason or "").
  OptionField& Custom(OptionField field, std::function<OptionValue(const T&)> get,
                      std::function<void(T&, const OptionValue&)> set,
                      std::function<std::string(const T&)> check = nullptr);
  // The same for an option that is member `member` (or part of it: several
  // options may set one member, a subset).
  template <typename M>
  OptionField& Custom(M T::*member, OptionField field, std::function<OptionValue(const T&)> get,
                      std::function<void(T&, const OptionValue&)> set,
                      std::function<std::string(const T&)> check = nullptr) {
    PlaceMember(member);
    return Custom(std::move(field), std::move(get), std::move(set), std::move(check));
  }
  // The options of a nested struct, member `member` of T (its members are
  // named "<member_name>.<theirs>"), on the surfaces of `surfaces` only,
  // without the options named in `skip` (still checked, as the nested
  // struct's Check() checks them, but set by T itself).
  template <typename S>
  void Nest(S T::*member, const char* member_name, const OptionTable<S>& table,
            unsigned surfaces = kEverywhere, std::vector<std::string> skip = {});
  // The description of an option already added, to adjust it (e.g. the
  // `absent` value of a nested option in this context).
  OptionField& Modify(const std::string& name);
  // A rule between options: "" or the reason (options marked `name`).
  void Rule(std::function<std::string(const T&)> rule) {
    AddRule([rule](const void* o) { return rule(*static_cast<const T*>(o)); });
  }

  OptionValue Get(const T& o, const std::string& name) const {
    return OptionTableBase::Get(&o, name);
  }
  void Set(T& o, const std::string& name, const OptionValue& v) const {
    OptionTableBase::Set(&o, name, v);
  }
  void SetText(T& o, const std::string& name, const std::string& text) const {
    OptionTableBase::SetText(&o, name, text);
  }
  std::string Check(const T& o) const { return CheckAll(&o); }

 private:
  OptionField& Added() { return entries_.back().field; }
  template <typename M>
  void PlaceMember(M T::*member) {
    const T& d = Defaults();
    const size_t offset = static_cast<size_t>(reinterpret_cast<const char*>(&(d.*member)) -
                                              reinterpret_cast<const char*>(&d));
    Place({offset, sizeof(M), alignof(M)});
  }
  static const T& Defaults() {
    static const T defaults{};
    return defaults;
  }
};

// ---- implementation of the templates --------------------------------------

template <typename T>
template <typename M>
OptionField& OptionTable<T>::Number(const std::string& name, M T::*member, const char* member_name,
                                    OptionRange range, const std::string& help,
                                    unsigned surfaces) {
  namespace oi = option_table_internal;
  static_assert(std::is_arithmetic<M>::value && !std::is_same<M, bool>::value,
                "Number: an int, int64_t, uint64_t or double member");
  PlaceMember(member);
  Entry e;
  e.field.name = name;
  e.field.member = member_name;
  e.field.help = help;
  e.field.range = range.Text();
  e.field.bounds = range;
  e.field.surfaces = surfaces;
  if constexpr (std::is_floating_point<M>::value) {
    e.field.kind = OptionKind::kDouble;
    e.get = [member](const void* o) -> OptionValue {
      return static_cast<double>(static_cast<const T*>(o)->*member);
    };
    e.set = [member, name](void* o, const OptionValue& v) {
      static_cast<T*>(o)->*member = static_cast<M>(oi::ToDouble(v, name));
    };
    e.check = [member, name, range](const void* o) -> std::string {
      const double v = static_cast<const T*>(o)->*member;
      return range.Contains(v) ? "" : oi::OutOfRange(name, range.Text(), oi::FormatValue(v));
    };
  } else if constexpr (std::is_same<M, uint64_t>::value) {
    e.field.kind = OptionKind::kUint64;
    e.get = [member](const void* o) -> OptionValue { return static_cast<const T*>(o)->*member; };
    e.set = [member, name](void* o, const OptionValue& v) {
      static_cast<T*>(o)->*member = oi::ToUint64(v, name);
    };
    e.check = [member, name, range](const void* o) -> std::string {
      const uint64_t v = static_cast<const T*>(o)->*member;
      return range.any() || range.Contains(static_cast<double>(v))
                 ? ""
                 : oi::OutOfRange(name, range.Text(), std::to_string(v));
    };
  } else {
    static_assert(std::is_signed<M>::value, "Number: signed whole numbers, or uint64_t");
    e.field.kind = OptionKind::kInt;
    e.get = [member](const void* o) -> OptionValue {
      return static_cast<int64_t>(static_cast<const T*>(o)->*member);
    };
    const std::string range_text = range.Text();
    e.set = [member, name, range_text](void* o, const OptionValue& v) {
      static_cast<T*>(o)->*member = static_cast<M>(oi::ToInt64(
          v, name, std::numeric_limits<M>::min(), std::numeric_limits<M>::max(), range_text));
    };
    e.check = [member, name, range](const void* o) -> std::string {
      const int64_t v = static_cast<const T*>(o)->*member;
      return range.Contains(static_cast<double>(v))
                 ? ""
                 : oi::OutOfRange(name, range.Text(), std::to_string(v));
    };
  }
  e.field.default_text = Text(e.get(&Defaults()));
  AddEntry(std::move(e));
  return Added();
}

template <typename T>
OptionField& OptionTable<T>::Bool(const std::string& name, bool T::*member,
                                  const char* member_name, const std::string& help, BoolFlag flag,
                                  unsigned surfaces) {
  PlaceMember(member);
  Entry e;
  e.field.name = name;
  e.field.member = member_name;
  e.field.kind = OptionKind::kBool;
  e.field.help = help;
  e.field.range = "true or false";
  e.field.surfaces = surfaces;
  e.field.bool_flag = flag;
  e.get = [member](const void* o) -> OptionValue { return static_cast<const T*>(o)->*member; };
  e.set = [member, name](void* o, const OptionValue& v) {
    static_cast<T*>(o)->*member = option_table_internal::ToBool(v, name);
  };
  e.check = [](const void*) { return std::string(); };
  e.field.default_text = Text(e.get(&Defaults()));
  AddEntry(std::move(e));
  return Added();
}

template <typename T>
OptionField& OptionTable<T>::String(const std::string& name, std::string T::*member,
                                  const char* member_name, const std::string& help,
                                  unsigned surfaces) {
  PlaceMember(member);
  Entry e;
  e.field.name = name;
  e.field.member = member_name;
  e.field.kind = OptionKind::kText;
  e.field.help = help;
  e.field.range = "any text";
  e.field.surfaces = surfaces;
  e.get = [member](const void* o) -> OptionValue { return static_cast<const T*>(o)->*member; };
  e.set = [member, name](void* o, const OptionValue& v) {
    static_cast<T*>(o)->*member = option_table_internal::ToString(v, name);
  };
  e.check = [](const void*) { return std::string(); };
  e.field.default_text = OptionTableBase::Text(e.get(&Defaults()));
  AddEntry(std::move(e));
  return Added();
}

template <typename T>
template <typename E, typename Parse, typename Name>
OptionField& OptionTable<T>::Choice(const std::string& name, E T::*member, const char* member_name,
                                    std::vector<E> values, Parse parse, Name to_name,
                                    const std::string& help, unsigned surfaces) {
  PlaceMember(member);
  Entry e;
  e.field.name = name;
  e.field.member = member_name;
  e.field.kind = OptionKind::kChoice;
  e.field.help = help;
  e.field.surfaces = surfaces;
  for (const E& v : values) e.field.choices.push_back(to_name(v));
  for (size_t i = 0; i < e.field.choices.size(); ++i) {
    e.field.range += (i == 0 ? "" : i + 1 == e.field.choices.size() ? " or " : ", ") +
                     e.field.choices[i];
  }
  e.get = [member, to_name](const void* o) -> OptionValue {
    return std::string(to_name(static_cast<const T*>(o)->*member));
  };
  e.set = [member, name, parse](void* o, const OptionValue& v) {
    static_cast<T*>(o)->*member = parse(option_table_internal::ToString(v, name));
  };
  const std::string range = e.field.range;
  e.check = [member, name, values, range](const void* o) -> std::string {
    const E v = static_cast<const T*>(o)->*member;
    for (const E& known : values) {
      if (known == v) return "";
    }
    return "`" + name + "` must be " + range + " (got an unknown value)";
  };
  e.field.default_text = OptionTableBase::Text(e.get(&Defaults()));
  AddEntry(std::move(e));
  return Added();
}

template <typename T>
template <typename E, typename Parse, typename Name>
OptionField& OptionTable<T>::List(const std::string& name, std::vector<E> T::*member,
                                  const char* member_name, std::vector<E> values, Parse parse,
                                  Name to_name, const std::string& help, unsigned surfaces) {
  PlaceMember(member);
  Entry e;
  e.field.name = name;
  e.field.member = member_name;
  e.field.kind = OptionKind::kList;
  e.field.help = help;
  e.field.surfaces = surfaces;
  for (const E& v : values) e.field.choices.push_back(to_name(v));
  for (size_t i = 0; i < e.field.choices.size(); ++i) {
    e.field.range += (i == 0 ? "" : i + 1 == e.field.choices.size() ? " and " : ", ") +
                     e.field.choices[i];
  }
  e.field.range = "some of " + e.field.range;
  e.get = [member, to_name](const void* o) -> OptionValue {
    std::vector<std::string> names;
    for (const E& v : static_cast<const T*>(o)->*member) names.push_back(to_name(v));
    return names;
  };
  e.set = [member, name, parse](void* o, const OptionValue& v) {
    std::vector<E> items;
    for (const std::string& item : option_table_internal::ToList(v, name)) {
      if (item.empty()) throw InvalidArgument("`" + name + "` has an empty item");
      items.push_back(parse(item));
    }
    static_cast<T*>(o)->*member = std::move(items);
  };
  e.check = [member, name, values](const void* o) -> std::string {
    const std::vector<E>& list = static_cast<const T*>(o)->*member;
    if (list.empty()) return "`" + name + "` is empty";
    for (size_t i = 0; i < list.size(); ++i) {
      if (std::find(values.begin(), values.end(), list[i]) == values.end())
        return "`" + name + "` holds an unknown value";
      for (size_t j = 0; j < i; ++j) {
        if (list[i] == list[j]) return "`" + name + "` repeats a value";
      }
    }
    return "";
  };
  e.field.default_text = OptionTableBase::Text(e.get(&Defaults()));
  AddEntry(std::move(e));
  return Added();
}

template <typename T>
OptionField& OptionTable<T>::Custom(OptionField field, std::function<OptionValue(const T&)> get,
                                    std::function<void(T&, const OptionValue&)> set,
                                    std::function<std::string(const T&)> check) {
  Entry e;
  e.field = std::move(field);
  e.get = [get](const void* o) { return get(*static_cast<const T*>(o)); };
  e.set = [set](void* o, const OptionValue& v) { set(*static_cast<T*>(o), v); };
  if (check) {
    e.check = [check](const void* o) { return check(*static_cast<const T*>(o)); };
  } else {
    e.check = [](const void*) { return std::string(); };
  }
  e.field.default_text = OptionTableBase::Text(e.get(&Defaults()));
  AddEntry(std::move(e));
  return Added();
}

template <typename T>
OptionField& OptionTable<T>::Modify(const std::string& name) {
  for (Entry& e : entries_) {
    if (e.field.name == name) return e.field;
  }
  throw std::logic_error("OptionTable::Modify: no option " + name + " in " + what_);
}

template <typename T>
template <typename S>
void OptionTable<T>::Nest(S T::*member, const char* member_name, const OptionTable<S>& table,
                          unsigned surfaces, std::vector<std::string> skip) {
  PlaceMember(member);
  for (const Entry& inner : table.entries()) {
    if (std::find(skip.begin(), skip.end(), inner.field.name) != skip.end()) continue;
    Entry e;
    e.field = inner.field;
    e.field.surfaces &= surfaces;
    e.field.member = std::string(member_name) + "." + inner.field.member;
    const auto get = inner.get;
    const auto set = inner.set;
    const auto check = inner.check;
    e.get = [member, get](const void* o) { return get(&(static_cast<const T*>(o)->*member)); };
    e.set = [member, set](void* o, const OptionValue& v) { set(&(static_cast<T*>(o)->*member), v); };
    e.check = [member, check](const void* o) { return check(&(static_cast<const T*>(o)->*member)); };
    // The default of the nested struct inside this one (it may differ from
    // the nested struct's own).
    e.field.default_text = OptionTableBase::Text(e.get(&Defaults()));
    AddEntry(std::move(e));
  }
  // The nested struct's own rules hold inside this one, and so do the
  // ranges of the options left out.
  const OptionTableBase* inner_table = &table;
  const bool all_added = skip.empty();
  AddRule([member, inner_table, all_added](const void* o) {
    const void* inner = &(static_cast<const T*>(o)->*member);
    return all_added ? inner_table->CheckRules(inner) : inner_table->CheckAll(inner);
  });
}

}  // namespace placedb
