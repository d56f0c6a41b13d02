// placedb bench: matching speed against the paper's BFMatcher loop.
#include <fmt/format.h>

#include "placedb/eval/bench.h"
#include "placedb/cli/flags.h"
#include "placedb/exe/command.h"

namespace placedb {
namespace cli {
namespace {

class BenchCommand : public Command {
 public:
  CLI::App* Register(CLI::App& app) override {
    auto* cmd = app.add_subcommand(
        "bench", "time matching per query: placedb vs the paper's OpenCV BFMatcher loop");
    db_.Add(cmd, "");
    source_.Add(cmd, "query frames");
    cmd->add_option("--queries", options_.num_queries,
                    "number of query frames (0: all) [0, 1000000]")
        ->capture_default_str();
    cmd->add_option("--seed", options_.seed, "seed of the query selection")->capture_default_str();
    cmd->add_option("--repeat", options_.repeat, "passes over the queries per method [1, 1000]")
        ->capture_default_str();
    AddThreadsOption(cmd, options_.threads, "threads of the multi-threaded pass");
    query_.Add(cmd);
    cmd->add_option("--json", json_, "write the timings as JSON to this file ('-': stdout)");
    return cmd;
  }

  int Run() override {
    const QueryOptions query = query_.Get();
    const PlaceDatabase db = db_.Open();
    const BenchReport r = RunBench(db, source_.Read(), options_, query);
    fmt::print("bench of {}: {}", db_.dir, FormatBenchReport(r));
    nlohmann::json j = BenchReportToJson(r);
    j["database"] = db_.dir;
    WriteJson(json_, j);
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
