// placedb experiment: the paper's experiments in one command (every
// feature x crop x resize x verification setting on one dataset), resumable,
// with a report.
#include <fmt/format.h>

#include "placedb/cli/flags.h"
#include "placedb/cli/options.h"
#include "placedb/exe/command.h"
#include "placedb/util/check.h"

namespace placedb {
namespace cli {
namespace {

class ExperimentCommand : public Command {
 public:
  CLI::App* Register(CLI::App& app) override {
    auto* cmd = app.add_subcommand(
        "experiment",
        "the paper's experiments: build and evaluate every feature x crop x resize x "
        "verification setting on one dataset; writes results.json and report.html");
    source_.Add(cmd);
    cmd->add_option("--db-images", db_images_,
                    "database frames from another image folder or list (the paper's training "
                    "sequence); default: the query source");
    cmd->add_option("--db-tum", db_tum_,
                    "database frames from another TUM RGB-D folder; default: the query source")
        ->excludes(cmd->get_option("--db-images"));
    cmd->add_option("--db-first", db_first_, "first database frame id")->capture_default_str();
    cmd->add_option("--db-last", db_last_, "last database frame id (0: to the end)")
        ->capture_default_str();
    AddOptionFlags(cmd, &truth_);
    AddOptionFlags(cmd, &options_);
    cmd->get_option("--all")->excludes(cmd->get_option("--queries"));
    cmd->add_option("--out", out_, "the experiment's folder (resumed when it holds this "
                                   "experiment)")
        ->required();
    cmd->add_flag("--no-report", no_report_, "write results.json only, no report.html");
    cmd->add_flag("--quiet", quiet_, "no progress");
    cmd->footer(
        "Examples:\n"
        "  placedb experiment --images data/rtabmap_loop/images --db-last 40 --first 41 \\\n"
        "    --truth data/rtabmap_loop/ground_truth.csv --out experiment\n"
        "  placedb experiment --tum data/tum_fr3_office_32 --db-last 16 --first 17 --features orb \\\n"
        "    --crop none --resize 1 --index bow --search bow --out experiment_bow\n");
    return cmd;
  }

  int Run() override {
    ExperimentOptions options = options_;
    options.progress = !quiet_;
    PLACEDB_CHECK_OPTIONS(options);

    ExperimentData data;
    data.queries = source_.Read();
    data.queries_from = source_.Describe();
    // The database's frames: the query source's, or another folder read
    // the same way.
    SourceArgs db_source = source_;
    if (!db_images_.empty() || !db_tum_.empty()) {
      db_source.bag.clear();
      db_source.source.images = db_images_;
      db_source.source.tum = db_tum_;
    }
    db_source.source.first = db_first_;
    db_source.source.last = db_last_;
    data.database = db_source.Read();
    data.database_from = db_source.Describe();

    const GroundTruth truth = MakeGroundTruth(truth_, source_.source);

    const ExperimentSummary s = RunExperiment(data, truth, options, out_);
    fmt::print("experiment: {} settings ({} finished earlier), {} queries each, database {} "
               "({} frames), queries {}\n",
               s.num_settings, s.num_reused, s.num_queries, data.database_from,
               data.database.size(), data.queries_from);
    fmt::print("results     {}\n", s.results);
    fmt::print("pictures    {} in {}/pictures\n", s.pictures.size(), out_);
    if (!no_report_) fmt::print("report      {}\n", WriteExperimentReport(out_));
    return 0;
  }

 private:
  SourceArgs source_;
  std::string db_images_, db_tum_;
  int db_first_ = 1, db_last_ = 0;
  GroundTruthOptions truth_;
  std::string out_;
  ExperimentOptions options_;
  bool no_report_ = false, quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> MakeExperimentCommand() { return std::make_unique<ExperimentCommand>(); }

}  // namespace cli
}  // namespace placedb
