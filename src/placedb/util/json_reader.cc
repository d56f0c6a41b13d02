#include "placedb/util/json_reader.h"

#include <cmath>

#include "placedb/util/check.h"

namespace placedb {

namespace {
[[noreturn]] void FailJson(JsonOrigin origin, const std::string& message) {
  if (origin == JsonOrigin::kDatabaseFile) PLACEDB_THROW_CORRUPT(message);
  PLACEDB_THROW_INVALID(message);
}
}  // namespace

nlohmann::json ParseJson(std::string_view text, const std::string& where, JsonOrigin origin,
                         size_t max_bytes) {
  if (text.size() > max_bytes) {
    FailJson(origin, where + ": " + std::to_string(text.size()) + " bytes of JSON, more than the " +
                         std::to_string(max_bytes) + " allowed");
  }
  // The nesting, outside strings (a string's brackets are text).
  int depth = 0;
  bool in_string = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\') {
        ++i;
      } else if (c == '"') {
        in_string = false;
      }
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth) {
        FailJson(origin, where + ": JSON nested deeper than " + std::to_string(kMaxJsonDepth) +
                             " levels (at byte " + std::to_string(i) + ")");
      }
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    FailJson(origin, where + ": not valid JSON (" + e.what() + ")");
  }
}

JsonReader::JsonReader(const nlohmann::json& j, std::string where, JsonOrigin origin)
    : j_(j), where_(std::move(where)), origin_(origin) {
  if (!j_.is_object()) Fail("", "is not a JSON object");
}

void JsonReader::Fail(const std::string& field, const std::string& what) const {
  const std::string message = where_ + (field.empty() ? "" : "." + field) + " " + what;
  if (origin_ == JsonOrigin::kDatabaseFile) PLACEDB_THROW_CORRUPT(message);
  PLACEDB_THROW_INVALID(message);
}

bool JsonReader::Has(const char* key) const { return j_.contains(key); }

const nlohmann::json& JsonReader::Member(const char* key) const {
  const auto it = j_.find(key);
  if (it == j_.end()) Fail(key, "is missing");
  return *it;
}

JsonReader JsonReader::Child(const char* key) const {
  const nlohmann::json& v = Member(key);
  if (!v.is_object()) Fail(key, "is not a JSON object");
  return JsonReader(v, where_ + "." + key, origin_);
}

double JsonReader::Number(const char* key) const {
  const nlohmann::json& v = Member(key);
  if (!v.is_number()) Fail(key, "is not a number");
  const double d = v.get<double>();
  if (!std::isfinite(d)) Fail(key, "is not finite");
  return d;
}

int64_t JsonReader::Integer(const char* key, int64_t lo, int64_t hi) const {
  const nlohmann::json& v = Member(key);
  if (!v.is_number_integer()) Fail(key, "is not an integer");
  if (v.is_number_unsigned() && v.get<uint64_t>() > static_cast<uint64_t>(INT64_MAX))
    Fail(key, "is out of range");
  const int64_t i = v.get<int64_t>();
  if (i < lo || i > hi) {
    Fail(key, "is out of range [" + std::to_string(lo) + ", " + std::to_string(hi) + "] (got " +
                  std::to_string(i) + ")");
  }
  return i;
}

uint64_t JsonReader::Unsigned(const char* key) const {
  const nlohmann::json& v = Member(key);
  if (!v.is_number_integer()) Fail(key, "is not an integer");
  if (!v.is_number_unsigned() && v.get<int64_t>() < 0) Fail(key, "is negative");
  return v.get<uint64_t>();
}

bool JsonReader::Boolean(const char* key) const {
  const nlohmann::json& v = Member(key);
  if (!v.is_boolean()) Fail(key, "is not true or false");
  return v.get<bool>();
}

std::string JsonReader::String(const char* key) const {
  const nlohmann::json& v = Member(key);
  if (!v.is_string()) Fail(key, "is not a string");
  return v.get<std::string>();
}

void JsonReader::Read(const char* key, double* out) const {
  if (Has(key)) *out = Number(key);
}
void JsonReader::Read(const char* key, int* out) const {
  if (Has(key)) *out = static_cast<int>(Integer(key, INT32_MIN, INT32_MAX));
}
void JsonReader::Read(const char* key, bool* out) const {
  if (Has(key)) *out = Boolean(key);
}
void JsonReader::Read(const char* key, std::string* out) const {
  if (Has(key)) *out = String(key);
}

std::string DumpJson(const nlohmann::json& j, int indent) {
  return j.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace placedb
