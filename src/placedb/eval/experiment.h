// The paper's experiments as one run: the grid of settings (feature ORB/SURF
// x crop none/chroma x resize 1, 1/4, 1/16 x verification on/off) on one
// dataset, every setting's database built and evaluated on the same random
// validation queries, and one folder with everything:
//
//   OUT/experiment.json      what was asked (resuming checks it is the same)
//   OUT/databases/NAME/      the databases, one per feature x crop x resize
//   OUT/settings/NAME.json   one finished setting: its build and evaluation
//   OUT/pictures/*.png       match pictures, crop illustrations, failures
//   OUT/results.json         every setting, every query (answer, correct or
//                            not, scores, latency per stage, database bytes)
//   OUT/report.html          the report (WriteExperimentReport)
//
// A setting is finished once its file in settings/ exists (written
// atomically): an interrupted run started again with the same arguments
// skips what is finished and redoes nothing else.
#pragma once

#include <string>
#include <vector>

#include "placedb/dataset/frame.h"
#include "placedb/eval/evaluate.h"
#include "placedb/eval/ground_truth.h"
#include "placedb/builder/build.h"
#include "placedb/query/result.h"
#include "placedb/util/option_table.h"

namespace placedb {

struct ExperimentSetting {
  FeatureType features = FeatureType::kOrb;
  CropMode crop = CropMode::kNone;
  int resize = 1;
  bool verify = true;
  bool sequence = false;     // evaluated with sequence evidence (EvalOptions::sequence)
  bool whole_image = false;  // the whole-image channel scores (QueryOptions::whole_image_weight)

  // "orb_chroma_r4": the database this setting queries.
  std::string DatabaseName() const;
  // "orb_chroma_r4_verify" / "..._noverify": file names, JSON keys.
  std::string Name() const;
  // "ORB chroma 1/4 verified": for people.
  std::string Label() const;
};

struct ExperimentOptions {
  // The grid: every combination is one setting. Each list non-empty, without
  // repeats; resizes from {1, 4, 16}. Defaults: the paper's whole grid with
  // verification on and off (24 settings).
  std::vector<FeatureType> features = {FeatureType::kOrb, FeatureType::kSurf};
  std::vector<CropMode> crops = {CropMode::kNone, CropMode::kChroma};
  std::vector<int> resizes = {1, 4, 16};
  std::vector<bool> verify = {true, false};
  // Sequence evidence and the whole-image channel, per setting: off by
  // default (on: eval with `sequence`; the query's whole_image_weight, or
  // kWholeImageWeight when it is 0).
  std::vector<bool> sequence = {false};
  std::vector<bool> whole_image = {false};
  static constexpr double kWholeImageWeight = 10.0;
  // Everything else of a build (crop options, extractor settings, PNG level,
  // threads); features.type, crop and resize are set per setting.
  BuildOptions build;
  // Everything else of a query; verify.enabled is set per setting. Default
  // top_k 10, for recall@k up to 10.
  QueryOptions query = DefaultQuery();
  // Queries: how many, which seed, or all; progress is overridden by
  // `progress` below.
  EvalOptions eval;
  // Queries drawn as match pictures (cropped vs uncropped). Range [0, 20].
  // Default 3.
  int num_pictures = 3;
  // Failed queries drawn in the report's grid. Range [0, 100]. Default 12.
  int num_failures = 12;
  // Start afresh, deleting what OUT holds from an earlier experiment.
  // Default false: resume when the arguments are the same, else an error.
  bool overwrite = false;
  // Progress on a terminal. Default true.
  bool progress = true;

  static QueryOptions DefaultQuery() {
    QueryOptions q;
    q.top_k = 10;
    return q;
  }
  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<ExperimentOptions>& Table();
  std::string Check() const;
  // The settings in run order: feature, crop, resize, verify (on first).
  std::vector<ExperimentSetting> Grid() const;
};

// Where the database and the queries come from: one sequence split in
// ranges, or two (the paper's training and validation sequences).
struct ExperimentData {
  std::vector<Frame> database;
  std::vector<Frame> queries;
  std::string database_from;  // descriptions, e.g. "images:data/x [1..40]"
  std::string queries_from;
};

struct ExperimentSummary {
  int num_settings = 0;
  int num_reused = 0;  // settings already finished by an earlier run
  int num_queries = 0;
  std::vector<std::string> pictures;  // written, relative to the folder
  std::string results;                // path of results.json
};

// Runs the experiment into `out_dir` (created). Throws InvalidArgument for
// bad options or data, or when `out_dir` holds an experiment with other
// arguments (without overwrite); CorruptDatabase when a file the experiment
// wrote there (experiment.json, a finished setting's results) is damaged;
// IoError for failed writes.
ExperimentSummary RunExperiment(const ExperimentData& data, const GroundTruth& truth,
                                const ExperimentOptions& options, const std::string& out_dir);

// Writes OUT/report.html from OUT/results.json with the report script
// (make_report.py; Python 3 with matplotlib), self-contained: figures are
// embedded. Returns the path. NotFound naming what is missing when
// results.json, the script, python3 or matplotlib cannot be found;
// CorruptDatabase when the script cannot use results.json; IoError when it
// cannot be run; InternalError when it fails otherwise. The script is looked up in
// $PLACEDB_REPORT_SCRIPT, then the installed share/placedb/, then the source tree this was built
// from.
std::string WriteExperimentReport(const std::string& out_dir);

}  // namespace placedb
