// placedb bench: matching speed against the paper's BFMatcher loop.
#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "placedb/cli/flags.h"
#include "placedb/cli/options.h"
#include "placedb/exe/command.h"
#include "placedb/util/json_reader.h"

namespace placedb {
namespace cli {
namespace {

class BenchCommand : public Command {
 public:
  CLI::App* Register(CLI::App& app) override {
    auto* cmd = app.add_subcommand(
        "bench", "time matching per query: placedb vs the paper's OpenCV BFMatcher loop");
    db_.Add(cmd, /*threads=*/false);
    source_.Add(cmd);
    AddOptionFlags(cmd, &options_);
    query_.Add(cmd);
    cmd->add_option("--json", json_, "write the timings as JSON to this file ('-': stdout)");
    cmd->footer(
        "Examples:\n"
        "  placedb bench --db office.db --images data/rtabmap_loop/images --first 41 --last 84\n"
        "  placedb bench --db office.db --images data/rtabmap_loop/images --first 41 --json - > bench.json\n");
    return cmd;
  }

  int Run() override {
    const QueryOptions query = query_.Get();
    const PlaceDatabase db = db_.Open();
    const BenchReport r = RunBench(db, source_.Read(), options_, query);
    fmt::print("bench of {}: {}", db_.dir, FormatBenchReport(r));
    nlohmann::json j = nlohmann::json::parse(BenchReportJson(r));
    j["database"] = db_.dir;
    WriteJson(json_, DumpJson(j, 2));
    return r.rankings_that_differ == 0 ? 0 : 3;
  }

 private:
  DatabaseArgs db_;
  QueryArgs query_;
  SourceArgs source_;
  BenchOptions options_;
  std::string json_;
};

}  // namespace

std::unique_ptr<Command> MakeBenchCommand() { return std::make_unique<BenchCommand>(); }

}  // namespace cli
}  // namespace placedb
