// Command-line flags made from option tables (util/option_table.h): every
// option a table shows on the command line (kCommandLine) becomes a flag,
// with the table's help, range and the struct's current value as default,
// bound to the struct: a value is parsed by the table (SetText) as the flag
// is read, and a bad one is an InvalidArgument naming the flag.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "placedb/util/option_table.h"

namespace placedb {
namespace cli {

// Adds the flags of `table`'s command-line options, but those named in
// `skip`, to `cmd`, bound to `*options` (which must outlive the parse).
void AddOptionFlags(CLI::App* cmd, const OptionTableBase& table, void* options,
                    const std::vector<std::string>& skip = {});
template <typename T>
void AddOptionFlags(CLI::App* cmd, T* options, const std::vector<std::string>& skip = {}) {
  AddOptionFlags(cmd, T::Table(), options, skip);
}

// Whether AddOptionFlags makes a flag of `field` when told to skip `skip`:
// a command-line option not named there. (`placedb options` reports the
// same rule.)
bool IsFlag(const OptionField& field, const std::vector<std::string>& skip);

// What AddOptionFlags bound: which command took which table's options (but
// `skip`), in the order they were bound. `placedb options` prints them.
struct BoundTable {
  std::string command;  // the sub-command's name ("query")
  const OptionTableBase* table;
  std::vector<std::string> skip;
};
std::vector<BoundTable> BoundTables();

// The table of every options struct an entry point of the library takes
// (FrameSourceOptions, BuildOptions, OpenOptions, QueryOptions, ...); every
// other options struct is nested in one of these (OrbOptions inside
// ExtractorOptions inside BuildOptions), and its options appear there with
// the surfaces the nesting gives them. `placedb options --json` reports
// these tables in full, so the tests can hold the command line and the
// Python module to them; option_tables_test checks that every table of the
// library is one of these or nested in one.
std::vector<const OptionTableBase*> AllOptionTables();

// The flag an option name is written as in messages: the flag a table
// bound in this program spells for it ("--no-images" for store_images), or
// the name with dashes.
std::string FlagOf(const std::string& name);

// The flag of an option as CLI11 finds it ("--top-k" for "--top-k"; the
// first name of "--verify,!--no-verify").
std::string FlagName(const OptionField& field);

}  // namespace cli
}  // namespace placedb
