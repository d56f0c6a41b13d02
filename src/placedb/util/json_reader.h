// Strict reading of JSON from outside (manifests, results received over the
// wire): every field is checked for its type and range, and a bad one throws
// with the path of the field ("manifest.settings.resize is not an integer"),
// never nlohmann's own exceptions, never a silent conversion (true is not 1,
// 2147483648 is not an int, 1.5 is not an integer).
#pragma once

#include <cstddef>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>

namespace placedb {

// Where the JSON came from, which decides the error a bad field is.
enum class JsonOrigin {
  kCaller,        // InvalidArgument: a result received over the wire, a caller's JSON
  kDatabaseFile,  // CorruptDatabase: a manifest (or another file placedb wrote)
};

// The limits of JSON text read from outside (ParseJson). Nothing placedb
// writes nests deeper than 8 levels; a deeper text is hostile or damaged, and
// refusing it before nlohmann builds it keeps every later walk (dump, copy,
// the Python conversion, all recursive) shallow.
constexpr int kMaxJsonDepth = 64;
// A database's manifest (settings, counts, names) is a few KiB.
constexpr size_t kMaxManifestBytes = size_t{1} << 20;

// `text` parsed as JSON, refusing text longer than `max_bytes` or nesting
// arrays and objects deeper than kMaxJsonDepth (checked by one scan of the
// text before it is parsed: no recursion, no allocation) and text that is not
// JSON; the error is of `origin` (CorruptDatabase for a file placedb wrote,
// else InvalidArgument) and names `where`. Every JSON read from a file or a
// message goes through it.
nlohmann::json ParseJson(std::string_view text, const std::string& where, JsonOrigin origin,
                         size_t max_bytes);

class JsonReader {
 public:
  // A bad field throws the error of `origin`. `where` names `j`.
  JsonReader(const nlohmann::json& j, std::string where, JsonOrigin origin = JsonOrigin::kCaller);

  const nlohmann::json& json() const { return j_; }
  const std::string& where() const { return where_; }
  bool Has(const char* key) const;

  // Required fields.
  const nlohmann::json& Member(const char* key) const;
  JsonReader Child(const char* key) const;  // must be an object
  double Number(const char* key) const;     // finite
  int64_t Integer(const char* key, int64_t lo, int64_t hi) const;
  // A non-negative integer of the full 64-bit range (seeds, checksums).
  uint64_t Unsigned(const char* key) const;
  bool Boolean(const char* key) const;
  std::string String(const char* key) const;

  // Optional fields: `*out` is left as it is when the key is absent.
  void Read(const char* key, double* out) const;
  void Read(const char* key, int* out) const;  // any int; ranges are Check()'s
  void Read(const char* key, bool* out) const;
  void Read(const char* key, std::string* out) const;

  [[noreturn]] void Fail(const std::string& field, const std::string& what) const;

 private:
  const nlohmann::json& j_;
  std::string where_;
  JsonOrigin origin_;
};

// JSON text of `j` (nlohmann's dump with `indent`; -1: one line) that never
// throws on strings that are not UTF-8 (paths are bytes): every byte that is
// not part of well-formed UTF-8 becomes U+FFFD, the replacement character, so
// the output is always valid UTF-8 JSON. Every JSON placedb writes goes
// through it.
std::string DumpJson(const nlohmann::json& j, int indent = -1);

}  // namespace placedb
