// placedb experiment: the paper's grid of settings on one dataset, as one
// folder with results.json and report.html.
#include <fmt/format.h>

#include "placedb/eval/experiment.h"
#include "placedb/cli/flags.h"
#include "placedb/exe/command.h"
#include "placedb/util/check.h"

namespace placedb {
namespace cli {
namespace {

// "a,b,c" -> {"a", "b", "c"}; an empty item is an error naming the flag.
std::vector<std::string> SplitList(const std::string& text, const std::string& flag) {
  std::vector<std::string> items;
  size_t start = 0;
  while (true) {
    const size_t comma = text.find(',', start);
    const std::string item = text.substr(start, comma == std::string::npos ? std::string::npos
                                                                            : comma - start);
    if (item.empty()) PLACEDB_THROW_INVALID("`", flag, "` has an empty item in '", text, "'");
    items.push_back(item);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return items;
}

class ExperimentCommand : public Command {
 public:
  CLI::App* Register(CLI::App& app) override {
    auto* cmd = app.add_subcommand(
        "experiment",
        "the paper's experiments: build and evaluate every feature x crop x resize x "
        "verification setting on one dataset; writes results.json and report.html");
    source_.Add(cmd, "query frames (and the database's, unless --db-images/--db-tum)");
    cmd->add_option("--db-images", db_source_.images,
                    "database frames from another image folder or list (the paper's training "
                    "sequence); default: the query source");
    cmd->add_option("--db-tum", db_source_.tum,
                    "database frames from another TUM RGB-D folder; default: the query source");
    cmd->add_option("--db-first", db_source_.first, "first database frame id")
        ->capture_default_str();
    cmd->add_option("--db-last", db_source_.last, "last database frame id (0: to the end)")
        ->capture_default_str();
    truth_.Add(cmd);
    AddQuerySelectionOptions(cmd, options_.eval);
    cmd->add_option("--features", features_, "features of the grid: orb, surf or both")
        ->capture_default_str();
    cmd->add_option("--crop", crops_, "crops of the grid: none, chroma or both")
        ->capture_default_str();
    cmd->add_option("--resize", resizes_, "stored-area divisors of the grid, from 1,4,16")
        ->capture_default_str();
    cmd->add_option("--verification", verification_,
                    "verification of the grid: on, off or both")
        ->capture_default_str();
    AddExtractorOptions(cmd, options_.build.features);
    AddCropOptions(cmd, options_.build.crop_options);
    cmd->add_option("--png-compression", options_.build.png_compression, "PNG level [0, 9]")
        ->capture_default_str();
    AddThreadsOption(cmd, options_.build.threads, "building the databases");
    query_.options = ExperimentOptions::DefaultQuery();
    query_.Add(cmd);
    // The grid sets verification; a prior means nothing for random queries.
    cmd->remove_option(cmd->get_option("--verify"));
    cmd->remove_option(cmd->get_option("--prior-keyframe"));
    cmd->add_option("--pictures", options_.num_pictures,
                    "queries drawn as match pictures, cropped vs uncropped [0, 20]")
        ->capture_default_str();
    cmd->add_option("--failures", options_.num_failures,
                    "failed queries drawn in the report's grid [0, 100]")
        ->capture_default_str();
    cmd->add_option("--out", out_, "the experiment's folder (resumed when it holds this "
                                   "experiment)")
        ->required();
    cmd->add_flag("--overwrite", options_.overwrite,
                  "start afresh, deleting the folder's earlier experiment");
    cmd->add_flag("--no-report", no_report_, "write results.json only, no report.html");
    cmd->add_flag("--quiet", quiet_, "no progress");
    return cmd;
  }

  int Run() override {
    ExperimentOptions options = options_;
    options.query = query_.Get();
    options.progress = !quiet_;
    options.features.clear();
    for (const std::string& f : SplitList(features_, "features"))
      options.features.push_back(ParseFeatureType(f));
    options.crops.clear();
    for (const std::string& c : SplitList(crops_, "crop"))
      options.crops.push_back(ParseCropMode(c));
    options.resizes.clear();
    for (const std::string& r : SplitList(resizes_, "resize")) {
      if (r != "1" && r != "4" && r != "16") {
        PLACEDB_THROW_INVALID("`resize` takes 1, 4 and 16 (got '", r, "')");
      }
      options.resizes.push_back(std::stoi(r));
    }
    options.verify.clear();
    for (const std::string& v : SplitList(verification_, "verification")) {
      if (v != "on" && v != "off") {
        PLACEDB_THROW_INVALID("`verification` takes on and off (got '", v, "')");
      }
      options.verify.push_back(v == "on");
    }
    PLACEDB_CHECK_OPTIONS(options);

    ExperimentData data;
    data.queries = source_.Read();
    data.queries_from = source_.Describe();
    SourceArgs db_source = source_;
    if (!db_source_.images.empty() || !db_source_.tum.empty()) {
      if (!db_source_.images.empty() && !db_source_.tum.empty()) {
        PLACEDB_THROW_INVALID("`db_images` and `db_tum` exclude each other");
      }
      db_source = SourceArgs();
      db_source.images = db_source_.images;
      db_source.tum = db_source_.tum;
      db_source.frame_size = source_.frame_size;
      db_source.tum_options = source_.tum_options;
      db_source.image_read = source_.image_read;
    }
    db_source.first = db_source_.first;
    db_source.last = db_source_.last;
    data.database = db_source.Read();
    data.database_from = db_source.Describe();

    const GroundTruth truth = truth_.Get(source_, "experiment");

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
  SourceArgs db_source_;
  TruthArgs truth_;
  std::string out_;
  std::string features_ = "orb,surf", crops_ = "none,chroma", resizes_ = "1,4,16";
  std::string verification_ = "on,off";
  ExperimentOptions options_;
  QueryArgs query_;
  bool no_report_ = false, quiet_ = false;
};

}  // namespace

std::unique_ptr<Command> MakeExperimentCommand() { return std::make_unique<ExperimentCommand>(); }

}  // namespace cli
}  // namespace placedb
