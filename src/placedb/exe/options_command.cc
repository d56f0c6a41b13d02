// placedb options: every option of every command, from the option tables:
// its flag, Python keyword, default, range and help. --markdown writes the
// README's table of options (scripts/option_tables.py keeps it current);
// --json every option of every table of the library with where it appears
// (the tests hold the command line and the Python module to it).
#include <fmt/format.h>

#include <iostream>
#include <nlohmann/json.hpp>

#include <map>
#include <set>

#include "placedb/cli/flags.h"
#include "placedb/cli/options.h"
#include "placedb/exe/command.h"
#include "placedb/util/json_reader.h"

namespace placedb {
namespace cli {
namespace {

// A cell of a Markdown table: pipes escaped, option names as flags.
std::string Cell(const std::string& text) {
  std::string out;
  for (const char c : FormatOptionNames(text, FlagOf)) {
    if (c == '|') out += "\\|";
    else out += c;
  }
  return out;
}

class OptionsCommand : public Command {
 public:
  CLI::App* Register(CLI::App& app) override {
    auto* cmd = app.add_subcommand(
        "options", "every option of every command: flag, Python keyword, default, range, help");
    cmd->add_flag("--markdown", markdown_, "as Markdown tables (the README's)");
    cmd->add_flag("--json", json_,
                  "every option of every table of the library as JSON, with the commands "
                  "whose flags set it");
    cmd->footer(
        "Examples:\n"
        "  placedb options\n"
        "  placedb options --json | python3 -m json.tool\n");
    return cmd;
  }

  int Run() override {
    if (markdown_ && json_) throw InvalidArgument("`markdown` and `json` exclude each other");
    if (json_) {
      PrintJson();
      return 0;
    }
    // Each table once, with the commands that take it and the options any
    // of them shows.
    struct Use {
      const OptionTableBase* table;
      std::vector<std::string> commands;
      std::set<std::string> shown;
    };
    std::vector<Use> uses;
    for (const BoundTable& b : BoundTables()) {
      if (b.command == "options") continue;
      Use* use = nullptr;
      for (Use& u : uses) {
        if (u.table == b.table) use = &u;
      }
      if (use == nullptr) {
        uses.push_back({b.table, {}, {}});
        use = &uses.back();
      }
      if (std::find(use->commands.begin(), use->commands.end(), b.command) == use->commands.end())
        use->commands.push_back(b.command);
      for (const auto& e : b.table->entries()) {
        if (IsFlag(e.field, b.skip)) use->shown.insert(e.field.name);
      }
    }
    for (const Use& u : uses) {
      std::string commands;
      for (const std::string& c : u.commands) commands += (commands.empty() ? "" : ", ") + c;
      if (markdown_) {
        fmt::print("\n**{}** ({})\n\n", u.table->what(), commands);
        fmt::print("| flag | Python | default | range | |\n| --- | --- | --- | --- | --- |\n");
      } else {
        fmt::print("\n{} ({}):\n", u.table->what(), commands);
      }
      for (const auto& e : u.table->entries()) {
        const OptionField& f = e.field;
        if (u.shown.count(f.name) == 0) continue;
        const std::string python = (f.surfaces & kPython) ? f.name : "";
        const std::string shown_default = f.default_text.empty() ? "''" : f.default_text;
        const std::string range = f.kind == OptionKind::kBool ? "true, false" : f.range;
        if (markdown_) {
          fmt::print("| `{}` | {} | {} | {} | {} |\n", FlagName(f),
                     python.empty() ? "" : "`" + python + "`", Cell(shown_default), Cell(range),
                     Cell(f.help));
        } else {
          fmt::print("  {:<26} {:<12} {} ({})\n", FlagName(f), shown_default,
                     FormatOptionNames(f.help, FlagOf), FormatOptionNames(range, FlagOf));
        }
      }
    }
    return 0;
  }

 private:
  // {"tables": [{"table", "commands", "options": [{"name", "flag", "kind",
  // "default", "range", "help", "command_line", "python", "manifest",
  // "shown_by"}]}]}: "shown_by" lists the commands with a flag for the
  // option (through any table they bound, nested ones included).
  static void PrintJson() {
    std::map<std::string, std::set<std::string>> shown_by;
    std::map<const OptionTableBase*, std::set<std::string>> commands;
    for (const BoundTable& b : BoundTables()) {
      if (b.command == "options") continue;
      commands[b.table].insert(b.command);
      for (const auto& e : b.table->entries()) {
        if (IsFlag(e.field, b.skip)) shown_by[e.field.name].insert(b.command);
      }
    }
    nlohmann::json tables = nlohmann::json::array();
    for (const OptionTableBase* table : AllOptionTables()) {
      nlohmann::json options = nlohmann::json::array();
      for (const auto& e : table->entries()) {
        const OptionField& f = e.field;
        const auto shown = shown_by.find(f.name);
        options.push_back({{"name", f.name},
                           {"flag", FlagName(f)},
                           {"kind", OptionKindName(f.kind)},
                           {"default", f.default_text},
                           {"range", f.range},
                           {"help", f.help},
                           {"command_line", (f.surfaces & kCommandLine) != 0},
                           {"python", (f.surfaces & kPython) != 0},
                           {"manifest", (f.surfaces & kManifest) != 0},
                           {"shown_by", shown == shown_by.end() ? std::set<std::string>()
                                                                : shown->second}});
      }
      tables.push_back(
          {{"table", table->what()}, {"commands", commands[table]}, {"options", options}});
    }
    std::cout << DumpJson({{"tables", tables}}, 2) << "\n";
  }

  bool markdown_ = false;
  bool json_ = false;
};

}  // namespace

std::unique_ptr<Command> MakeOptionsCommand() { return std::make_unique<OptionsCommand>(); }

}  // namespace cli
}  // namespace placedb
