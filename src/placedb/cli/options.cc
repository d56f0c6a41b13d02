#include "placedb/cli/options.h"

#include <algorithm>
#include <map>
#include <mutex>

#include "placedb/placedb.h"
#include "placedb/util/error.h"

namespace placedb {
namespace cli {
namespace {
// Option name -> the flag bound for it in this program.
std::mutex& FlagsMutex() {
  static std::mutex m;
  return m;
}
std::map<std::string, std::string>& BoundFlags() {
  static std::map<std::string, std::string> flags;
  return flags;
}
std::vector<BoundTable>& Bound() {
  static std::vector<BoundTable> bound;
  return bound;
}

}  // namespace

std::vector<BoundTable> BoundTables() {
  std::lock_guard<std::mutex> lock(FlagsMutex());
  return Bound();
}

std::vector<const OptionTableBase*> AllOptionTables() {
  return {&FrameSourceOptions::Table(), &BuildOptions::Table(),       &OpenOptions::Table(),
          &QueryOptions::Table(),       &GroundTruthOptions::Table(), &EvalOptions::Table(),
          &BenchOptions::Table(),       &ExperimentOptions::Table(),  &VoteOptions::Table(),
          &AddOptions::Table()};
}

std::string FlagOf(const std::string& name) {
  {
    std::lock_guard<std::mutex> lock(FlagsMutex());
    const auto it = BoundFlags().find(name);
    if (it != BoundFlags().end()) return it->second;
  }
  std::string flag = "--" + name;
  std::replace(flag.begin(), flag.end(), '_', '-');
  return flag;
}

std::string FlagName(const OptionField& field) {
  const size_t comma = field.flag.find(',');
  return comma == std::string::npos ? field.flag : field.flag.substr(0, comma);
}

namespace {

const char* TypeName(OptionKind kind) {
  switch (kind) {
    case OptionKind::kBool:
      return "BOOL";
    case OptionKind::kInt:
    case OptionKind::kUint64:
      return "INT";
    case OptionKind::kDouble:
      return "FLOAT";
    case OptionKind::kText:
      return "TEXT";
    case OptionKind::kChoice:
      return "NAME";
    case OptionKind::kList:
      return "LIST";
    case OptionKind::kNumbers:
      return "NUMBERS";
  }
  return "TEXT";
}

// "help [range]", option names written as flags.
std::string HelpOf(const OptionField& f) {
  std::string help = f.help;
  if (f.kind != OptionKind::kBool && f.kind != OptionKind::kText && !f.range.empty() &&
      f.range != "any") {
    help += f.kind == OptionKind::kChoice || f.kind == OptionKind::kList ? ": " + f.range
            : f.range.find_first_of("[(") == 0                           ? " " + f.range
                                                                         : " (" + f.range + ")";
  }
  return FormatOptionNames(help, FlagOf);
}

}  // namespace

bool IsFlag(const OptionField& field, const std::vector<std::string>& skip) {
  return (field.surfaces & kCommandLine) != 0 &&
         std::find(skip.begin(), skip.end(), field.name) == skip.end();
}

void AddOptionFlags(CLI::App* cmd, const OptionTableBase& table, void* options,
                    const std::vector<std::string>& skip) {
  {
    std::lock_guard<std::mutex> lock(FlagsMutex());
    Bound().push_back({cmd->get_name(), &table, skip});
  }
  for (const OptionTableBase::Entry& entry : table.entries()) {
    const OptionField& f = entry.field;
    if (!IsFlag(f, skip)) continue;
    {
      std::lock_guard<std::mutex> lock(FlagsMutex());
      BoundFlags()[f.name] = FlagName(f);
    }
    const std::string help = HelpOf(f);
    const OptionTableBase::Entry* e = &entry;  // tables live as long as the program
    if (f.kind == OptionKind::kBool && f.bool_flag != BoolFlag::kValue) {
      switch (f.bool_flag) {
        case BoolFlag::kSwitch:
          cmd->add_flag_function(
              f.flag, [e, options](int64_t) { e->set(options, true); }, help);
          break;
        case BoolFlag::kNegatable: {
          // CLI11 counts --name as 1 and --no-name as -1. The default is
          // said in words: "--verify,--no-verify=true" reads ambiguously.
          const bool on = OptionTableBase::Text(entry.get(options)) == "true";
          const std::string positive = f.flag.substr(0, f.flag.find(','));
          cmd->add_flag_function(
              f.flag, [e, options](int64_t count) { e->set(options, count > 0); },
              help + (on ? " (default: on; --no-" + positive.substr(2) + " turns it off)"
                         : " (default: off; " + positive + " turns it on)"));
          break;
        }
        case BoolFlag::kInverted:
          cmd->add_flag_function(
              f.flag, [e, options](int64_t) { e->set(options, false); }, help);
          break;
        case BoolFlag::kValue:
          break;
      }
      continue;
    }
    const std::string name = f.name;
    CLI::Option* option = cmd->add_option_function<std::string>(
        f.flag,
        [&table, options, name](const std::string& text) { table.SetText(options, name, text); },
        help);
    option->type_name(TypeName(f.kind));
    const std::string current = OptionTableBase::Text(entry.get(options));
    if (!current.empty()) option->default_str(current);
  }
}

}  // namespace cli
}  // namespace placedb
