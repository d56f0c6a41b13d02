// The option tables of evaluation, benchmarks and the paper's experiments
// (util/option_table.h).
#include "placedb/eval/bench.h"
#include "placedb/eval/evaluate.h"
#include "placedb/eval/experiment.h"
#include "placedb/eval/ground_truth.h"
#include "placedb/util/check.h"
#include "placedb/util/option_table.h"

namespace placedb {

const OptionTable<PoseThresholds>& PoseThresholds::Table() {
  static const OptionTable<PoseThresholds> table = [] {
    using O = PoseThresholds;
    OptionTable<O> t("ground-truth thresholds");
    t.Number("max_dist", PLACEDB_MEMBER(O, max_distance_m), OptionRange::LeftOpen(0, 1e6),
             "poses: a keyframe within this distance (m) ...", kCallers);
    t.Number("max_angle", PLACEDB_MEMBER(O, max_angle_deg), OptionRange::LeftOpen(0, 180),
             "... and this viewing angle (deg) of the query is correct", kCallers);
    return t;
  }();
  return table;
}

std::string PoseThresholds::Check() const { return Table().Check(*this); }

const OptionTable<GroundTruthOptions>& GroundTruthOptions::Table() {
  static const OptionTable<GroundTruthOptions> table = [] {
    using O = GroundTruthOptions;
    OptionTable<O> t("ground truth");
    t.String("truth", PLACEDB_MEMBER(O, truth),
             "CSV of true matches (query_id,keyframe ids); needed with `images`, else poses decide",
             kCallers);
    t.Nest(PLACEDB_MEMBER(O, poses), PoseThresholds::Table(), kCallers);
    return t;
  }();
  return table;
}

std::string GroundTruthOptions::Check() const { return Table().Check(*this); }

const OptionTable<EvalOptions>& EvalOptions::Table() {
  static const OptionTable<EvalOptions> table = [] {
    using O = EvalOptions;
    OptionTable<O> t("evaluation options");
    t.Number("queries", PLACEDB_MEMBER(O, num_queries), OptionRange::Closed(1, 1e6),
             "number of random queries (the paper's 50)", kCallers);
    t.Bool("all", PLACEDB_MEMBER(O, all), "use every query with ground truth", BoolFlag::kSwitch,
           kCallers);
    t.Number("seed", PLACEDB_MEMBER(O, seed), OptionRange::Any(),
             "seed of the random query selection", kCallers);
    t.Bool("sequence", PLACEDB_MEMBER(O, sequence),
           "replay the queries in id order as a moving robot's frames: each with the previous "
           "answer as its prior (`prior_keyframe`), and answered with sequence evidence "
           "(`sequence_*`) beside the single-frame answers",
           BoolFlag::kSwitch, kCallers);
    t.Nest(PLACEDB_MEMBER(O, sequence_options), SequenceOptions::Table(), kCallers);
    t.Bool("strict", PLACEDB_MEMBER(O, strict),
           "refuse an evaluation that cannot mean anything (queries that are database frames, "
           "no answerable query, truth that judges no keyframe); default: warn",
           BoolFlag::kSwitch, kCallers);
    t.Choice("baseline", PLACEDB_MEMBER(O, baseline),
             {EvalBaseline::kNone, EvalBaseline::kHog, EvalBaseline::kSeqSlam, EvalBaseline::kBoth},
             ParseEvalBaseline, EvalBaselineName,
             "also answer the same queries with the classic whole-image methods against the "
             "keyframes' whole frames: none, hog (HOG of the whole frame), seqslam (SeqSLAM, 10 "
             "frames) or both",
             kCallers);
    // The command line's --quiet turns it off.
    t.Bool("progress", PLACEDB_MEMBER(O, progress), "draw a progress bar (only on a terminal)",
           BoolFlag::kValue, kPython);
    return t;
  }();
  return table;
}

std::string EvalOptions::Check() const { return Table().Check(*this); }

const OptionTable<BenchOptions>& BenchOptions::Table() {
  static const OptionTable<BenchOptions> table = [] {
    using O = BenchOptions;
    OptionTable<O> t("bench options");
    t.Number("queries", PLACEDB_MEMBER(O, num_queries), OptionRange::Closed(0, 1e6),
             "query frames timed (0: all)", kCommandLine);
    t.Number("seed", PLACEDB_MEMBER(O, seed), OptionRange::Any(), "seed of the query selection",
             kCommandLine);
    t.Number("repeat", PLACEDB_MEMBER(O, repeat), OptionRange::Closed(1, 1000),
             "passes over the queries per method (the best counts)", kCommandLine);
    t.Number("threads", PLACEDB_MEMBER(O, threads), OptionRange::Closed(0, 1024),
             "threads of the multi-threaded pass (0: one per core)", kCommandLine);
    return t;
  }();
  return table;
}

std::string BenchOptions::Check() const { return Table().Check(*this); }

namespace {
int ParseResize(const std::string& text) {
  if (text == "1") return 1;
  if (text == "4") return 4;
  if (text == "16") return 16;
  PLACEDB_THROW_INVALID("`resize` takes 1, 4 and 16 (got '", text, "')");
}
std::string ResizeName(int r) { return std::to_string(r); }
bool ParseOnOff(const std::string& text, const char* name) {
  if (text == "on") return true;
  if (text == "off") return false;
  PLACEDB_THROW_INVALID("`", name, "` takes on and off (got '", text, "')");
}
bool ParseVerification(const std::string& text) { return ParseOnOff(text, "verification"); }
bool ParseSequenceEvidence(const std::string& text) {
  return ParseOnOff(text, "sequence_evidence");
}
bool ParseWholeImageScoring(const std::string& text) {
  return ParseOnOff(text, "whole_image_scoring");
}
const char* VerificationName(bool on) { return on ? "on" : "off"; }
}  // namespace

const OptionTable<ExperimentOptions>& ExperimentOptions::Table() {
  static const OptionTable<ExperimentOptions> table = [] {
    using O = ExperimentOptions;
    OptionTable<O> t("experiment options");
    // The grid.
    t.List("features", PLACEDB_MEMBER(O, features), {FeatureType::kOrb, FeatureType::kSurf},
           ParseFeatureType, FeatureTypeName, "features of the grid", kCallers);
    t.List("crop", PLACEDB_MEMBER(O, crops), {CropMode::kNone, CropMode::kChroma}, ParseCropMode,
           CropModeName, "crops of the grid", kCallers);
    t.List("resize", PLACEDB_MEMBER(O, resizes), {1, 4, 16}, ParseResize, ResizeName,
           "stored-area divisors of the grid", kCallers);
    t.List("verification", PLACEDB_MEMBER(O, verify), {true, false}, ParseVerification,
           VerificationName, "verification of the grid", kCallers);
    t.List("sequence_evidence", PLACEDB_MEMBER(O, sequence), {true, false}, ParseSequenceEvidence,
           VerificationName,
           "sequence evidence of the grid (on: queries in order, answered with `sequence_*`)",
           kCallers);
    t.List("whole_image_scoring", PLACEDB_MEMBER(O, whole_image), {true, false},
           ParseWholeImageScoring, VerificationName,
           "whole-image channel of the grid (on: `whole_image_weight`, 10 when it is 0)", kCallers);
    // Everything else of a build and a query; the grid sets the feature type,
    // crop, resize and verification, the experiment its own folder and
    // progress, and a prior means nothing for random queries.
    // The retrieval index and its vocabulary are every database's (bow
    // search needs `index` bow).
    t.Nest(PLACEDB_MEMBER(O, build), BuildOptions::Table(), kCallers,
           {"features", "crop", "resize", "extract_in_context", "store_images", "strict",
            "progress", "overwrite"});
    t.Nest(PLACEDB_MEMBER(O, query), QueryOptions::Table(), kCallers,
           {"verify", "prior_keyframe", "prior_pose"});
    t.Nest(PLACEDB_MEMBER(O, eval), EvalOptions::Table(), kCallers,
           {"sequence", "progress", "baseline"});
    t.Number("pictures", PLACEDB_MEMBER(O, num_pictures), OptionRange::Closed(0, 20),
             "queries drawn as match pictures, cropped vs uncropped", kCallers);
    t.Number("failures", PLACEDB_MEMBER(O, num_failures), OptionRange::Closed(0, 100),
             "failed queries drawn in the report's grid", kCallers);
    t.Bool("overwrite", PLACEDB_MEMBER(O, overwrite),
           "start afresh, deleting the folder's earlier experiment", BoolFlag::kSwitch, kCallers);
    // The command line's --quiet turns it off.
    t.Bool("progress", PLACEDB_MEMBER(O, progress), "progress on a terminal", BoolFlag::kValue,
           kPython);
    return t;
  }();
  return table;
}

std::string ExperimentOptions::Check() const {
  std::string error = Table().Check(*this);
  if (error.empty() && query.retrieval.method == RetrievalMethod::kBow &&
      build.index != IndexKind::kBow) {
    error = "`search` bow needs databases with a bag-of-words index: add `index` bow";
  }
  return error;
}

}  // namespace placedb
