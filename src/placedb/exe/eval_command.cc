// placedb eval: the paper's experiment against ground truth.
#include <fmt/format.h>

#include "placedb/eval/evaluate.h"
#include "placedb/cli/flags.h"
#include "placedb/exe/command.h"
#include "placedb/util/check.h"

namespace placedb {
namespace cli {
namespace {

class EvalCommand : public Command {
 public:
  CLI::App* Register(CLI::App& app) override {
    auto* cmd = app.add_subcommand(
        "eval",
        "evaluate a database on query frames with ground truth (recall, precision, "
        "latency, size)");
    db_.Add(cmd, "threads matching and verifying each query");
    source_.Add(cmd, "query frames");
    truth_.Add(cmd);
    AddQuerySelectionOptions(cmd, options_);
    cmd->add_flag("--sequence", options_.sequence,
                  "replay the queries in sequence order, each with the previous answer as its "
                  "prior (for --search cluster)");
    query_.Add(cmd);
    cmd->add_flag("--quiet", quiet_, "no progress bar");
    cmd->add_option("--json", json_, "write the report as JSON to this file ('-': stdout)");
    return cmd;
  }

  int Run() override {
    const QueryOptions query = query_.Get();
    const PlaceDatabase db = db_.Open();
    const std::vector<Frame> frames = source_.Read();
    const GroundTruth truth = truth_.Get(source_, "eval");
    EvalOptions options = options_;
    options.progress = !quiet_;
    const EvalReport r = Evaluate(db, frames, truth, options, query);
    fmt::print("eval of {} ({} keyframes, {} features) on {}\n", db_.dir, db.size(),
               FeatureTypeName(db.feature_type()), source_.Describe());
    fmt::print("{}", FormatEvalReport(r));
    nlohmann::json j = EvalReportToJson(r);
    j["database"] = db_.dir;
    j["queries_from"] = source_.Describe();
    j["seed"] = options.seed;
    j["settings"] = nlohmann::json::parse(db.manifest_json()).value("settings", nlohmann::json::object());
    WriteJson(json_, j);
    return 0;
  }

 private:
  DatabaseArgs db_;
  QueryArgs query_;
  SourceArgs source_;
  TruthArgs truth_;
  std::string json_;
  EvalOptions options_;
  bool quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> MakeEvalCommand() { return std::make_unique<EvalCommand>(); }

}  // namespace cli
}  // namespace placedb
