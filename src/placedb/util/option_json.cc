#include "placedb/util/option_json.h"

#include <map>
#include <set>
#include <vector>

#include "placedb/util/check.h"

namespace placedb {
namespace {

// "features.orb.max_features" -> {"features", "orb", "max_features"}.
std::vector<std::string> PathOf(const std::string& member) {
  std::vector<std::string> parts;
  size_t begin = 0;
  while (true) {
    const size_t dot = member.find('.', begin);
    parts.push_back(member.substr(begin, dot == std::string::npos ? dot : dot - begin));
    if (dot == std::string::npos) break;
    begin = dot + 1;
  }
  return parts;
}

// The value of `j` for an option of `kind`, or a reason it is not one
// (*reason set).
OptionValue ValueFromJson(const nlohmann::json& j, OptionKind kind, std::string* reason) {
  switch (kind) {
    case OptionKind::kBool:
      if (j.is_boolean()) return j.get<bool>();
      *reason = "is not true or false";
      return false;
    case OptionKind::kInt:
    case OptionKind::kUint64:
      if (j.is_number_unsigned()) return j.get<uint64_t>();
      if (j.is_number_integer()) return j.get<int64_t>();
      *reason = "is not a whole number";
      return int64_t{0};
    case OptionKind::kDouble:
      if (j.is_number_unsigned()) return j.get<uint64_t>();
      if (j.is_number_integer()) return j.get<int64_t>();
      if (j.is_number_float()) return j.get<double>();
      *reason = "is not a number";
      return 0.0;
    case OptionKind::kText:
    case OptionKind::kChoice:
      if (j.is_string()) return j.get<std::string>();
      *reason = "is not a string";
      return std::string();
    case OptionKind::kList: {
      std::vector<std::string> items;
      if (j.is_array()) {
        for (const nlohmann::json& item : j) {
          if (item.is_string()) {
            items.push_back(item.get<std::string>());
          } else if (item.is_number_integer()) {
            items.push_back(item.dump());
          } else if (item.is_boolean()) {
            items.push_back(item.get<bool>() ? "true" : "false");
          } else {
            *reason = "is not a list of names or whole numbers";
            return items;
          }
        }
        return items;
      }
      *reason = "is not a list";
      return items;
    }
    case OptionKind::kNumbers: {
      std::vector<double> numbers;
      if (j.is_null()) return numbers;
      if (j.is_array()) {
        for (const nlohmann::json& item : j) {
          if (!item.is_number()) {
            *reason = "is not a list of numbers";
            return numbers;
          }
          numbers.push_back(item.get<double>());
        }
        return numbers;
      }
      *reason = "is not a list of numbers or null";
      return numbers;
    }
  }
  *reason = "has an unknown kind";
  return false;
}

// Every key path `table` reads at `surface`, and the objects on the way.
struct Expected {
  std::set<std::string> leaves;
  std::set<std::string> objects;
};

Expected ExpectedKeys(const OptionTableBase& table, unsigned surface) {
  Expected e;
  for (const OptionTableBase::Entry& entry : table.entries()) {
    if ((entry.field.surfaces & surface) == 0) continue;
    e.leaves.insert(entry.field.member);
    const std::vector<std::string> path = PathOf(entry.field.member);
    std::string prefix;
    for (size_t i = 0; i + 1 < path.size(); ++i) {
      prefix += (i == 0 ? "" : ".") + path[i];
      e.objects.insert(prefix);
    }
  }
  return e;
}

void RefuseUnknownKeys(const JsonReader& reader, const Expected& expected,
                       const std::string& prefix) {
  for (const auto& [key, value] : reader.json().items()) {
    const std::string path = prefix.empty() ? key : prefix + "." + key;
    if (expected.objects.count(path) != 0) {
      RefuseUnknownKeys(reader.Child(key.c_str()), expected, path);
    } else if (expected.leaves.count(path) == 0) {
      reader.Fail(key, "is not a setting this placedb knows (written by a newer version?)");
    }
  }
}

}  // namespace

nlohmann::json OptionValueToJson(const OptionValue& value) {
  struct Visitor {
    nlohmann::json operator()(bool b) const { return b; }
    nlohmann::json operator()(int64_t i) const { return i; }
    nlohmann::json operator()(uint64_t u) const { return u; }
    nlohmann::json operator()(double d) const { return d; }
    nlohmann::json operator()(const std::string& s) const { return s; }
    nlohmann::json operator()(const std::vector<std::string>& l) const { return l; }
    nlohmann::json operator()(const std::vector<double>& l) const {
      return l.empty() ? nlohmann::json() : nlohmann::json(l);
    }
  };
  return std::visit(Visitor(), value);
}

nlohmann::json OptionsToJson(const OptionTableBase& table, const void* options, unsigned surface) {
  nlohmann::json j = nlohmann::json::object();
  for (const OptionTableBase::Entry& entry : table.entries()) {
    if ((entry.field.surfaces & surface) == 0) continue;
    nlohmann::json* at = &j;
    for (const std::string& part : PathOf(entry.field.member)) at = &(*at)[part];
    *at = OptionValueToJson(entry.get(options));
  }
  return j;
}

void OptionsFromJson(const OptionTableBase& table, const JsonReader& reader, void* options,
                     unsigned surface) {
  const Expected expected = ExpectedKeys(table, surface);
  RefuseUnknownKeys(reader, expected, "");
  for (const OptionTableBase::Entry& entry : table.entries()) {
    if ((entry.field.surfaces & surface) == 0) continue;
    const std::vector<std::string> path = PathOf(entry.field.member);
    // Walk down to the object that holds the key; a missing object is a
    // missing key.
    const nlohmann::json* at = &reader.json();
    std::string shown;
    bool present = true;
    for (size_t i = 0; i < path.size() && present; ++i) {
      shown += (i == 0 ? "" : ".") + path[i];
      if (!at->is_object()) reader.Fail(shown.substr(0, shown.rfind('.')), "is not a JSON object");
      const auto it = at->find(path[i]);
      if (it == at->end()) {
        present = false;
      } else {
        at = &*it;
      }
    }
    if (!present) {
      if (!entry.field.absent) reader.Fail(entry.field.member, "is missing");
      entry.set(options, *entry.field.absent);
      continue;
    }
    std::string reason;
    const OptionValue value = ValueFromJson(*at, entry.field.kind, &reason);
    if (!reason.empty()) reader.Fail(entry.field.member, reason);
    try {
      entry.set(options, value);
    } catch (const InvalidArgument& e) {
      reader.Fail(entry.field.member, "is not valid: " + std::string(e.what()));
    }
  }
}

}  // namespace placedb
