// Options as JSON, from their tables (util/option_table.h): the build
// settings a manifest keeps, the options an experiment records. Each option
// is a key at its member's path ("features.orb.max_features" is
// {"features": {"orb": {"max_features": ...}}}).
//
// Reading is strict: every option of the surface must be there (unless the
// table says what its absence means, for keys older files lack), with the
// right JSON type (true is not 1, 1.5 is not a whole number), and a key the
// table does not know is an error: a setting this placedb cannot honour is
// never silently dropped. Errors name the key's path.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "placedb/util/json_reader.h"
#include "placedb/util/option_table.h"

namespace placedb {

// The options of `surface` (kManifest, ...) as a JSON object.
nlohmann::json OptionsToJson(const OptionTableBase& table, const void* options, unsigned surface);
template <typename T>
nlohmann::json OptionsToJson(const T& options, unsigned surface = kManifest) {
  return OptionsToJson(T::Table(), &options, surface);
}

// Sets the options of `surface` from `j` (an object; `reader` names it in
// errors and says which error a bad field is: CorruptDatabase for a file,
// InvalidArgument for a caller's JSON). Other options keep their values.
// The struct's Check() is not run.
void OptionsFromJson(const OptionTableBase& table, const JsonReader& reader, void* options,
                     unsigned surface);
template <typename T>
void OptionsFromJson(const JsonReader& reader, T* options, unsigned surface = kManifest) {
  OptionsFromJson(T::Table(), reader, options, surface);
}

// The JSON of one value, and a value from JSON of the option's kind (for
// clients that take JSON: the experiment's record).
nlohmann::json OptionValueToJson(const OptionValue& value);

}  // namespace placedb
