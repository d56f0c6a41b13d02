#include "placedb/eval/experiment.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <set>

#include "placedb/builder/builder.h"
#include "placedb/eval/pictures.h"
#include "placedb/eval/report_json.h"
#include "placedb/image/feature_rich_crop.h"
#include "placedb/image/resize.h"
#include "placedb/query/query.h"
#include "placedb/session/place_database.h"
#include "placedb/session/storage_view.h"
#include "placedb/util/check.h"
#include "placedb/util/checksum.h"
#include "placedb/util/file_io.h"
#include "placedb/util/json_reader.h"
#include "placedb/util/option_json.h"
#include "placedb/util/options.h"

#ifndef PLACEDB_PYTHON
#define PLACEDB_PYTHON "/usr/bin/python3"
#endif
#ifndef PLACEDB_REPORT_SCRIPT_INSTALLED
#define PLACEDB_REPORT_SCRIPT_INSTALLED ""
#endif
#ifndef PLACEDB_REPORT_SCRIPT_SOURCE
#define PLACEDB_REPORT_SCRIPT_SOURCE ""
#endif

namespace placedb {
namespace fs = std::filesystem;

std::string ExperimentSetting::DatabaseName() const {
  return fmt::format("{}_{}_r{}", FeatureTypeName(features), CropModeName(crop), resize);
}

std::string ExperimentSetting::Name() const {
  return DatabaseName() + (verify ? "_verify" : "_noverify") + (sequence ? "_seq" : "") +
         (whole_image ? "_whole" : "");
}

std::string ExperimentSetting::Label() const {
  std::string feature = FeatureTypeName(features);
  for (char& c : feature) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return fmt::format("{} {} {} {}{}{}", feature, CropModeName(crop),
                     resize == 1 ? std::string("1") : fmt::format("1/{}", resize),
                     verify ? "verified" : "unverified", sequence ? " + sequence" : "",
                     whole_image ? " + whole image" : "");
}

std::vector<ExperimentSetting> ExperimentOptions::Grid() const {
  std::vector<ExperimentSetting> grid;
  for (const FeatureType f : features) {
    for (const CropMode c : crops) {
      for (const int r : resizes) {
        for (const bool v : verify) {
          for (const bool q : sequence) {
            for (const bool w : whole_image) grid.push_back({f, c, r, v, q, w});
          }
        }
      }
    }
  }
  return grid;
}

namespace {

// What identifies a list of frames: count, id range and a checksum of ids
// and paths.
nlohmann::json FramesIdentity(const std::vector<Frame>& frames, const std::string& from) {
  std::string all;
  for (const Frame& f : frames) all += fmt::format("{}\t{}\n", f.id, f.image_path);
  return {{"from", from},
          {"count", frames.size()},
          {"first_id", frames.empty() ? 0 : frames.front().id},
          {"last_id", frames.empty() ? 0 : frames.back().id},
          {"checksum", ChecksumHex(Checksum64(all.data(), all.size()))}};
}

BuildOptions BuildFor(const ExperimentOptions& o, const ExperimentSetting& s) {
  BuildOptions b = o.build;
  b.features.type = s.features;
  b.crop = s.crop;
  b.resize = s.resize;
  b.overwrite = true;
  b.progress = o.progress;
  return b;
}

QueryOptions QueryFor(const ExperimentOptions& o, const ExperimentSetting& s) {
  QueryOptions q = o.query;
  q.verify.enabled = s.verify;
  if (s.whole_image) {
    if (q.whole_image_weight <= 0.0) q.whole_image_weight = ExperimentOptions::kWholeImageWeight;
  } else {  // the channel off: no bonus and no candidates of its own
    q.whole_image_weight = 0.0;
    q.whole_image_candidates = 0;
  }
  return q;
}

EvalOptions SettingEval(EvalOptions eval, const ExperimentSetting& s) {
  eval.sequence = s.sequence;
  return eval;
}

nlohmann::json SettingJson(const ExperimentSetting& s) {
  return {{"name", s.Name()},
          {"label", s.Label()},
          {"database", s.DatabaseName()},
          {"features", FeatureTypeName(s.features)},
          {"crop", CropModeName(s.crop)},
          {"resize", s.resize},
          {"verify", s.verify},
          {"sequence", s.sequence},
          {"whole_image", s.whole_image}};
}

// A setting's results file holds a record per query: generous, but bounded.
constexpr size_t kMaxResultsFileBytes = size_t{1} << 30;

// A JSON file the experiment wrote into its folder: damaged, it is
// CorruptDatabase (the folder is ours, like a database).
nlohmann::json ReadJsonFile(const std::string& path) {
  return ParseJson(ReadFileToString(path), path, JsonOrigin::kDatabaseFile, kMaxResultsFileBytes);
}

// A finished setting's results (settings/<name>.json), read back to resume:
// every field the summary and the pictures read is checked, so that a
// damaged or edited file is CorruptDatabase naming the field, never a JSON
// library's exception.
nlohmann::json ReadSettingFile(const std::string& path, const std::vector<Frame>& queries) {
  nlohmann::json j = ReadJsonFile(path);
  const JsonReader file(j, path, JsonOrigin::kDatabaseFile);
  const JsonReader eval = file.Child("eval");
  eval.Integer("num_queries", 0, INT32_MAX);
  const nlohmann::json& records = eval.Member("queries");
  if (!records.is_array()) eval.Fail("queries", "is not an array");
  std::set<int64_t> ids;
  for (const Frame& f : queries) ids.insert(f.id);
  for (size_t i = 0; i < records.size(); ++i) {
    const JsonReader q(records[i], eval.where() + ".queries[" + std::to_string(i) + "]",
                       JsonOrigin::kDatabaseFile);
    if (ids.count(q.Integer("query_id", INT32_MIN, INT32_MAX)) == 0)
      q.Fail("query_id", "is not one of the experiment's query frames");
    q.Boolean("has_true_match_in_db");
    q.Boolean("correct_at_1");
    if (q.Boolean("unreadable")) continue;
    try {
      q.Member("result").get<QueryResult>();
    } catch (const InvalidArgument& e) {
      PLACEDB_THROW_CORRUPT(path, ": ", e.message());
    }
  }
  return j;
}

// The first key whose value differs between two objects ("" when equal).
std::string FirstDifference(const nlohmann::json& a, const nlohmann::json& b) {
  if (!a.is_object() || !b.is_object()) return a == b ? "" : "(the whole file)";
  std::set<std::string> keys;
  for (auto it = a.begin(); it != a.end(); ++it) keys.insert(it.key());
  for (auto it = b.begin(); it != b.end(); ++it) keys.insert(it.key());
  for (const std::string& k : keys) {
    if (!a.contains(k) || !b.contains(k) || a[k] != b[k]) return k;
  }
  return "";
}

// What OUT owns; --overwrite removes exactly these.
const char* const kOwned[] = {"experiment.json", "databases",   "settings", "pictures",
                              "results.json",    "report.html", "figures"};

void PrepareFolder(const std::string& out, const nlohmann::json& config, bool overwrite) {
  const fs::path dir(out);
  const fs::path config_path = dir / "experiment.json";
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec)) {
    PLACEDB_THROW_INVALID("the experiment's output ", out, " exists and is not a folder");
  }
  if (fs::is_directory(dir, ec) && !fs::is_empty(dir, ec) && !fs::exists(config_path, ec)) {
    PLACEDB_THROW_INVALID("the folder ", out,
                          " is not empty and holds no experiment: choose another `out`");
  }
  if (fs::exists(config_path, ec)) {
    if (overwrite) {
      for (const char* name : kOwned) {
        fs::remove_all(dir / name, ec);
        if (ec) PLACEDB_THROW_IO("cannot remove ", (dir / name).string(), ": ", ec.message());
      }
    } else {
      const nlohmann::json old = ReadJsonFile(config_path.string());
      const std::string diff = FirstDifference(old, config);
      if (!diff.empty()) {
        PLACEDB_THROW_INVALID("the folder ", out,
                              " holds an experiment with other arguments (they differ in '", diff,
                              "'): use the same arguments to resume, `overwrite` to start "
                              "afresh, or another `out`");
      }
    }
  }
  for (const char* sub : {"settings", "databases", "pictures"}) {
    fs::create_directories(dir / sub, ec);
    if (ec) PLACEDB_THROW_IO("cannot create ", (dir / sub).string(), ": ", ec.message());
  }
  WriteFileAtomic(config_path.string(), DumpJson(config, 2) + "\n");
}

// The settings of one database, finished or not.
struct DatabaseGroup {
  ExperimentSetting first;
  std::vector<ExperimentSetting> settings;
};

// Opens (or builds) the database of a setting.
PlaceDatabase OpenOrBuild(const ExperimentData& data, const ExperimentOptions& options,
                          const ExperimentSetting& s, const fs::path& out,
                          nlohmann::json* build_json) {
  const fs::path db_dir = out / "databases" / s.DatabaseName();
  const fs::path build_file = out / "databases" / (s.DatabaseName() + ".build.json");
  OpenOptions open;
  open.expected_features = s.features;
  std::error_code ec;
  if (fs::exists(build_file, ec) && fs::exists(db_dir, ec)) {
    // Whatever keeps the finished database from opening (damage, a build
    // killed half-way), it is built again.
    try {
      PlaceDatabase db = PlaceDatabase::Open(db_dir.string(), open);
      *build_json = ReadJsonFile(build_file.string());
      return db;
    } catch (const std::exception& e) {
      spdlog::warn("rebuilding {}: {}", db_dir.string(), e.what());
    }
  }
  fs::remove(build_file, ec);
  const BuildReport report =
      BuildDatabase(data.database, BuildFor(options, s), db_dir.string(), data.database_from);
  *build_json = BuildReportToJson(report, db_dir.string());
  WriteFileAtomic(build_file.string(), DumpJson(*build_json, 2) + "\n");
  return PlaceDatabase::Open(db_dir.string(), open);
}

// ---- pictures ------------------------------------------------------------

const nlohmann::json* FindRecord(const nlohmann::json& setting_json, int query_id) {
  for (const nlohmann::json& q : setting_json["eval"]["queries"]) {
    if (q["query_id"].get<int>() == query_id) return &q;
  }
  return nullptr;
}

// The keyframe a record answered with (ranked[0]), 0 when none.
int32_t AnswerOf(const nlohmann::json& record) {
  if (record["result"].is_null() || record["result"]["ranked"].empty()) return 0;
  return record["result"]["ranked"][0]["keyframe_id"].get<int32_t>();
}

void WritePng(const fs::path& path, const cv::Mat& image) {
  bool written = false;
  try {
    written = cv::imwrite(path.string(), image);
  } catch (const cv::Exception& e) {
    PLACEDB_THROW_IO("cannot write ", path.string(), ": ", e.what());
  }
  if (!written) PLACEDB_THROW_IO("cannot write ", path.string());
}

class PictureMaker {
 public:
  PictureMaker(const ExperimentData& data, const GroundTruth& truth,
               const ExperimentOptions& options, const fs::path& out,
               const std::map<std::string, nlohmann::json>& finished)
      : data_(data), truth_(truth), options_(options), out_(out), finished_(finished) {
    for (const Frame& f : data.queries) queries_[f.id] = f;
  }

  nlohmann::json Make() {
    nlohmann::json j;
    j["matches"] = Matches();
    j["crops"] = Crops();
    j["failures"] = Failures();
    j["failure_setting"] = failure_setting_;
    return j;
  }

 private:
  const PlaceDatabase& Db(const ExperimentSetting& s) {
    auto it = dbs_.find(s.DatabaseName());
    if (it == dbs_.end()) {
      OpenOptions open;
      open.expected_features = s.features;
      it = dbs_.emplace(s.DatabaseName(),
                        PlaceDatabase::Open((out_ / "databases" / s.DatabaseName()).string(), open))
               .first;
    }
    return it->second;
  }

  // The settings the pictures come from: the first feature, full size (or
  // the first resize), verified when the grid has it; one per crop mode.
  std::vector<ExperimentSetting> PictureSettings() const {
    const int resize =
        std::find(options_.resizes.begin(), options_.resizes.end(), 1) != options_.resizes.end()
            ? 1
            : options_.resizes.front();
    const bool verify =
        std::find(options_.verify.begin(), options_.verify.end(), true) != options_.verify.end();
    std::vector<ExperimentSetting> out;
    for (const CropMode c : options_.crops)
      out.push_back({options_.features.front(), c, resize, verify, false, false});
    return out;
  }

  nlohmann::json Matches() {
    nlohmann::json list = nlohmann::json::array();
    const std::vector<ExperimentSetting> settings = PictureSettings();
    const nlohmann::json& first = finished_.at(settings.front().Name());
    // Answerable queries, those the crop modes disagree on first.
    std::vector<int> differing, agreeing;
    for (const nlohmann::json& q : first["eval"]["queries"]) {
      if (q["unreadable"].get<bool>() || !q["has_true_match_in_db"].get<bool>()) continue;
      const int id = q["query_id"].get<int>();
      bool differs = false;
      for (const ExperimentSetting& s : settings) {
        const nlohmann::json* r = FindRecord(finished_.at(s.Name()), id);
        if (r != nullptr && (*r)["correct_at_1"] != q["correct_at_1"]) differs = true;
      }
      (differs ? differing : agreeing).push_back(id);
    }
    std::vector<int> chosen = differing;
    chosen.insert(chosen.end(), agreeing.begin(), agreeing.end());
    if (chosen.size() > static_cast<size_t>(options_.num_pictures))
      chosen.resize(options_.num_pictures);
    std::sort(chosen.begin(), chosen.end());
    ExperimentSetting verified;  // the pictures: verification on, neither channel
    verified.verify = true;
    const QueryOptions query = QueryFor(options_, verified);
    for (const int id : chosen) {
      const Frame& frame = queries_.at(id);
      const cv::Mat image = LoadFrameImage(frame);
      if (image.empty()) continue;
      // The chroma database's crop of each keyframe, for the matches lost.
      const ExperimentSetting* chroma = nullptr;
      for (const ExperimentSetting& s : settings) {
        if (s.crop == CropMode::kChroma) chroma = &s;
      }
      for (const ExperimentSetting& s : settings) {
        const nlohmann::json* r = FindRecord(finished_.at(s.Name()), id);
        const int32_t answer = r ? AnswerOf(*r) : 0;
        if (answer == 0) continue;
        const PlaceDatabase& db = Db(s);
        const MatchDetail d = db.Explain(db.Extract(image), answer, query);
        MatchPicture p;
        p.query = image;
        p.keyframe = LoadKeyframePicture(db, answer, &p.keyframe_is_original);
        if (p.keyframe.empty()) continue;
        p.detail = &d;
        const std::optional<Keyframe> k = db.FindKeyframe(answer);
        const bool correct = k.has_value() && truth_.IsCorrect(frame, *k);
        int num_lost = 0;
        if (s.crop == CropMode::kNone && chroma != nullptr && p.keyframe_is_original) {
          const std::optional<Keyframe> ck = Db(*chroma).FindKeyframe(answer);
          if (ck) {
            p.region = ck->crop;
            for (const cv::DMatch& m : d.matches) {
              const bool lost = !ck->crop.contains(cv::Point(d.keyframe_points[m.trainIdx]));
              p.lost.push_back(lost);
              num_lost += lost;
            }
          }
        } else if (s.crop == CropMode::kChroma && k && p.keyframe_is_original) {
          p.region = k->crop;
        }
        p.caption = fmt::format("query {} -> keyframe {} ({}), {}", id, answer,
                                correct ? "correct" : "wrong", s.Label());
        const std::string file = fmt::format("pictures/match_q{}_{}.png", id, CropModeName(s.crop));
        WritePng(out_ / file, DrawMatchPicture(p));
        list.push_back({{"query_id", id},
                        {"setting", s.Name()},
                        {"crop", CropModeName(s.crop)},
                        {"keyframe_id", answer},
                        {"correct", correct},
                        {"num_matches", d.matches.size()},
                        {"num_inliers", d.num_inliers},
                        {"num_lost", num_lost},
                        {"file", file}});
      }
    }
    return list;
  }

  nlohmann::json Crops() {
    nlohmann::json list = nlohmann::json::array();
    const CropOptions& co = options_.build.crop_options;
    bool have_winner = false, have_whole = false;
    size_t looked = 0;
    for (const Frame& f : data_.database) {
      if ((have_winner && have_whole) || looked >= 60) break;
      ++looked;
      const cv::Mat image = LoadFrameImage(f);
      if (image.empty()) continue;
      const CropResult crop = SelectFeatureRichCrop(image, co);
      if (crop.whole_image ? have_whole : have_winner) continue;
      (crop.whole_image ? have_whole : have_winner) = true;
      const std::string file = fmt::format("pictures/crop_{}.png", f.id);
      WritePng(out_ / file, DrawCropIllustration(image, crop, co, options_.resizes));
      nlohmann::json candidates = nlohmann::json::array();
      for (int c = 0; c < 3; ++c) {
        const CropCandidate& cand = crop.candidates[c];
        candidates.push_back({{"channel", ChromaChannelName(static_cast<ChromaChannel>(c))},
                              {"valid", cand.valid},
                              {"roi", {cand.roi.x, cand.roi.y, cand.roi.width, cand.roi.height}},
                              {"fast_keypoints", cand.fast_keypoints}});
      }
      list.push_back({{"frame_id", f.id},
                      {"file", file},
                      {"whole_image", crop.whole_image},
                      {"winner", crop.channel < 0
                                     ? "none"
                                     : ChromaChannelName(static_cast<ChromaChannel>(crop.channel))},
                      {"min_fast_keypoints", co.min_fast_keypoints},
                      {"candidates", candidates}});
    }
    return list;
  }

  nlohmann::json Failures() {
    nlohmann::json list = nlohmann::json::array();
    const ExperimentSetting s = PictureSettings().front();
    failure_setting_ = s.Name();
    const PlaceDatabase& db = Db(s);
    for (const nlohmann::json& q : finished_.at(s.Name())["eval"]["queries"]) {
      if (static_cast<int>(list.size()) >= options_.num_failures) break;
      if (q["unreadable"].get<bool>()) continue;
      const bool answerable = q["has_true_match_in_db"].get<bool>();
      const bool matched = q["result"]["matched"].get<bool>();
      if (answerable ? q["correct_at_1"].get<bool>() : !matched) continue;
      const int id = q["query_id"].get<int>();
      const Frame& frame = queries_.at(id);
      const int32_t answer = AnswerOf(q);
      int32_t true_id = 0;
      const StorageView view(db);
      for (const Keyframe& k : view.database().keyframes()) {
        if (truth_.IsCorrect(frame, k)) {
          true_id = k.id;
          break;
        }
      }
      bool original = true;
      std::vector<cv::Mat> images = {LoadFrameImage(frame)};
      std::vector<std::string> captions = {fmt::format("query {}", id)};
      images.push_back(answer ? LoadKeyframePicture(db, answer, &original) : cv::Mat());
      captions.push_back(answer ? fmt::format("answer: keyframe {}{}", answer,
                                              matched ? "" : " (below the threshold)")
                                : "no keyframe ranked");
      images.push_back(true_id ? LoadKeyframePicture(db, true_id, &original) : cv::Mat());
      captions.push_back(true_id ? fmt::format("a true keyframe: {}", true_id)
                                 : "the place is not in the database");
      const std::string file = fmt::format("pictures/failure_q{}.png", id);
      WritePng(out_ / file, DrawImageRow(images, captions, 200));
      list.push_back({{"query_id", id},
                      {"answer_id", answer},
                      {"matched", matched},
                      {"true_id", true_id},
                      {"file", file}});
    }
    return list;
  }

  const ExperimentData& data_;
  const GroundTruth& truth_;
  const ExperimentOptions& options_;
  const fs::path out_;
  const std::map<std::string, nlohmann::json>& finished_;
  std::map<int, Frame> queries_;
  std::map<std::string, PlaceDatabase> dbs_;
  std::string failure_setting_;
};

}  // namespace

ExperimentSummary RunExperiment(const ExperimentData& data, const GroundTruth& truth,
                                const ExperimentOptions& options, const std::string& out_dir) {
  PLACEDB_CHECK_OPTIONS(options);
  if (data.database.empty()) PLACEDB_THROW_INVALID("the experiment has no database frames");
  if (data.queries.empty()) PLACEDB_THROW_INVALID("the experiment has no query frames");
  const std::vector<Frame> selected = SelectQueries(data.queries, truth, options.eval);
  if (selected.empty()) {
    PLACEDB_THROW_INVALID("no query frame has ground truth (", truth.Describe(),
                          "); nothing to evaluate");
  }
  // Checked once, before any database is built, on the frames the
  // databases will hold (a crop or resize keeps each frame's id and pose).
  std::vector<Keyframe> would_be;
  for (const Frame& f : data.database) {
    Keyframe k;
    k.id = f.id;
    k.pose = f.pose;
    k.source = f.load ? std::string() : f.image_path;
    would_be.push_back(std::move(k));
  }
  ReportEvaluationDoubts(EvaluationDoubts(selected, would_be, truth), options.eval.strict);
  const std::vector<ExperimentSetting> grid = options.Grid();
  nlohmann::json names = nlohmann::json::array();
  for (const ExperimentSetting& s : grid) names.push_back(s.Name());
  EvalOptions eval = options.eval;
  eval.progress = options.progress;
  nlohmann::json build = BuildSettingsToJson(options.build);
  for (const char* per_setting : {"features", "crop", "resize"}) build.erase(per_setting);
  nlohmann::json query = OptionsToJson(options.query, kCallers);
  query["verify"].erase("enabled");
  const nlohmann::json config = {
      {"format", "placedb experiment 1"},
      {"settings", names},
      {"build", build},
      {"query", query},
      {"eval",
       {{"num_queries", eval.all ? 0 : eval.num_queries},
        {"all", eval.all},
        {"seed", eval.seed},
        {"sequence", eval.sequence}}},
      {"truth", truth.Describe()},
      {"database_frames", FramesIdentity(data.database, data.database_from)},
      {"query_frames", FramesIdentity(data.queries, data.queries_from)}};
  const fs::path out(out_dir);
  PrepareFolder(out_dir, config, options.overwrite);

  ExperimentSummary summary;
  summary.num_settings = static_cast<int>(grid.size());
  std::map<std::string, nlohmann::json> finished;
  std::vector<DatabaseGroup> groups;
  for (const ExperimentSetting& s : grid) {
    if (groups.empty() || groups.back().first.DatabaseName() != s.DatabaseName()) {
      groups.push_back({s, {}});
    }
    groups.back().settings.push_back(s);
  }
  int index = 0;
  for (const DatabaseGroup& g : groups) {
    std::vector<ExperimentSetting> todo;
    for (const ExperimentSetting& s : g.settings) {
      const fs::path file = out / "settings" / (s.Name() + ".json");
      std::error_code ec;
      if (fs::exists(file, ec)) {
        finished[s.Name()] = ReadSettingFile(file.string(), data.queries);
        ++summary.num_reused;
        ++index;
        if (options.progress) {
          fmt::print(stderr, "[{}/{}] {}: finished earlier\n", index, grid.size(), s.Label());
        }
      } else {
        todo.push_back(s);
      }
    }
    if (todo.empty()) continue;
    nlohmann::json build_json;
    const PlaceDatabase db = OpenOrBuild(data, options, g.first, out, &build_json);
    for (const ExperimentSetting& s : todo) {
      const EvalReport r =
          Evaluate(db, data.queries, truth, SettingEval(eval, s), QueryFor(options, s), false);
      nlohmann::json j = {{"setting", SettingJson(s)},
                          {"num_keyframes", db.size()},
                          {"build", build_json},
                          {"eval", EvalReportToJson(r)}};
      WriteFileAtomic((out / "settings" / (s.Name() + ".json")).string(), DumpJson(j) + "\n");
      finished[s.Name()] = std::move(j);
      ++index;
      if (options.progress) {
        fmt::print(stderr,
                   "[{}/{}] {}: {} correct of {} answerable ({} queries), recall@1 {}, {:.2f} "
                   "ms/query\n",
                   index, grid.size(), s.Label(), r.num_correct, r.num_answerable, r.num_queries,
                   r.num_answerable > 0 ? fmt::format("{:.3f}", r.recall_at_1) : "n/a",
                   r.latency_ms.mean);
      }
    }
  }
  summary.num_queries = finished.at(grid.front().Name())["eval"]["num_queries"].get<int>();

  nlohmann::json pictures;
  if (options.progress) fmt::print(stderr, "drawing the pictures\n");
  pictures = PictureMaker(data, truth, options, out, finished).Make();
  for (const char* kind : {"matches", "crops", "failures"}) {
    for (const nlohmann::json& p : pictures[kind]) summary.pictures.push_back(p["file"]);
  }
  nlohmann::json results = config;
  results["generated_by"] = "placedb experiment";
  // Pictures are drawn anew by every run: their numbers are not part of what
  // a resumed run must agree on.
  results["num_pictures"] = {{"matches", options.num_pictures}, {"failures", options.num_failures}};
  results["settings"] = nlohmann::json::array();
  for (const ExperimentSetting& s : grid) results["settings"].push_back(finished.at(s.Name()));
  results["pictures"] = pictures;
  summary.results = (out / "results.json").string();
  WriteFileAtomic(summary.results, DumpJson(results) + "\n");
  return summary;
}

// ---- the report -------------------------------------------------------------

namespace {
std::string FindReportScript() {
  if (const char* env = std::getenv("PLACEDB_REPORT_SCRIPT"); env != nullptr && *env != '\0') {
    std::error_code ec;
    if (!fs::is_regular_file(env, ec)) {
      PLACEDB_THROW_NOT_FOUND("PLACEDB_REPORT_SCRIPT names ", env, ", which is not a file");
    }
    return env;
  }
  for (const char* candidate : {PLACEDB_REPORT_SCRIPT_INSTALLED, PLACEDB_REPORT_SCRIPT_SOURCE}) {
    std::error_code ec;
    if (*candidate != '\0' && fs::is_regular_file(candidate, ec)) return candidate;
  }
  PLACEDB_THROW_NOT_FOUND("the report script make_report.py is not installed (looked in '",
                          PLACEDB_REPORT_SCRIPT_INSTALLED, "' and '", PLACEDB_REPORT_SCRIPT_SOURCE,
                          "'); set PLACEDB_REPORT_SCRIPT");
}

// Runs argv (no shell) and returns its exit status (-1: did not start).
int RunProgram(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const pid_t pid = fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    execv(argv[0], argv.data());
    _exit(127);
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) return -1;
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}
}  // namespace

std::string WriteExperimentReport(const std::string& out_dir) {
  const fs::path results = fs::path(out_dir) / "results.json";
  std::error_code ec;
  if (!fs::is_regular_file(results, ec)) {
    PLACEDB_THROW_NOT_FOUND("no results.json in ", out_dir, ": run the experiment first");
  }
  const std::string script = FindReportScript();
  const std::string python = PLACEDB_PYTHON;
  if (access(python.c_str(), X_OK) != 0) {
    PLACEDB_THROW_NOT_FOUND("the report needs ", python, " (Debian: apt-get install python3 ",
                            "python3-matplotlib)");
  }
  const std::string report = (fs::path(out_dir) / "report.html").string();
  // make_report.py's exit status: 1 bad input (it printed why), 3 no
  // matplotlib; RunProgram's -1 and 127: it did not run.
  const int status = RunProgram({python, script, out_dir});
  if (status == 3) {
    PLACEDB_THROW_NOT_FOUND("the report needs matplotlib for ", python,
                            " (Debian: apt-get install python3-matplotlib)");
  }
  if (status == -1 || status == 127) {
    PLACEDB_THROW_IO("cannot run the report script ", script, " with ", python);
  }
  if (status == 1) {
    PLACEDB_THROW_CORRUPT("the report script cannot use ", results.string(),
                          " (its message is above)");
  }
  if (status != 0) {
    PLACEDB_THROW_INTERNAL("the report script ", script, " failed (exit status ", status,
                           "); results.json is complete");
  }
  if (!fs::is_regular_file(report, ec)) {
    PLACEDB_THROW_INTERNAL("the report script wrote no ", report);
  }
  return report;
}

}  // namespace placedb
