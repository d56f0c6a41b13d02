// placedb eval: the paper's experiment against ground truth.
#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "placedb/cli/flags.h"
#include "placedb/cli/options.h"
#include "placedb/exe/command.h"
#include "placedb/util/check.h"
#include "placedb/util/json_reader.h"

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
    db_.Add(cmd);
    source_.Add(cmd);
    AddOptionFlags(cmd, &truth_);
    AddOptionFlags(cmd, &options_);
    cmd->get_option("--all")->excludes(cmd->get_option("--queries"));
    query_.Add(cmd);
    cmd->add_flag("--quiet", quiet_, "no progress bar");
    cmd->add_option("--json", json_, "write the report as JSON to this file ('-': stdout)");
    cmd->footer(
        "Examples:\n"
        "  placedb eval --db office.db --images data/rtabmap_loop/images --first 41 --last 84 \\\n"
        "    --truth data/rtabmap_loop/ground_truth.csv --all\n"
        "  placedb eval --db office_tum.db --tum data/tum_fr3_office_32 --first 17 --json report.json\n");
    return cmd;
  }

  int Run() override {
    const QueryOptions query = query_.Get();
    const PlaceDatabase db = db_.Open();
    const std::vector<Frame> frames = source_.Read();
    const GroundTruth truth = MakeGroundTruth(truth_, source_.source);
    EvalOptions options = options_;
    options.progress = !quiet_;
    const EvalReport r = Evaluate(db, frames, truth, options, query);
    fmt::print("eval of {} ({} keyframes, {} features) on {}\n", db_.dir, db.size(),
               FeatureTypeName(db.feature_type()), source_.Describe());
    fmt::print("{}", FormatEvalReport(r));
    nlohmann::json j = nlohmann::json::parse(EvalReportJson(r));
    j["database"] = db_.dir;
    j["queries_from"] = source_.Describe();
    j["seed"] = options.seed;
    j["settings"] = nlohmann::json::parse(db.manifest_json()).value("settings", nlohmann::json::object());
    WriteJson(json_, DumpJson(j, 2));
    return 0;
  }

 private:
  DatabaseArgs db_;
  QueryArgs query_;
  SourceArgs source_;
  GroundTruthOptions truth_;
  std::string json_;
  EvalOptions options_;
  bool quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> MakeEvalCommand() { return std::make_unique<EvalCommand>(); }

}  // namespace cli
}  // namespace placedb
