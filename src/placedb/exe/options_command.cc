// placedb options: every option of every command, from the option tables:
// its flag, Python keyword, default, range and help. --markdown writes the
// README's table of options (scripts/option_tables.py keeps it current).
#include <fmt/format.h>

#include <map>
#include <set>

#include "placedb/cli/flags.h"
#include "placedb/cli/options.h"
#include "placedb/exe/command.h"

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
    return cmd;
  }

  int Run() override {
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
        if ((e.field.surfaces & kCommandLine) &&
            std::find(b.skip.begin(), b.skip.end(), e.field.name) == b.skip.end())
          use->shown.insert(e.field.name);
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
  bool markdown_ = false;
};

}  // namespace

std::unique_ptr<Command> MakeOptionsCommand() { return std::make_unique<OptionsCommand>(); }

}  // namespace cli
}  // namespace placedb
