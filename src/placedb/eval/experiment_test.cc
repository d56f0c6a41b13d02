#include "placedb/eval/experiment.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "placedb/dataset/image_folder.h"
#include "placedb/dataset/match_truth.h"
#include "placedb/util/file_io.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
namespace fs = std::filesystem;
using testing_util::TempDir;
using testing_util::ThrowsWith;

const std::string kImages = PLACEDB_DATA_DIR "/rtabmap_loop/images";
const std::string kTruth = PLACEDB_DATA_DIR "/rtabmap_loop/ground_truth.csv";

ExperimentData SmallData() {
  ExperimentData d;
  d.database = ReadImages(kImages, 1, 20);
  d.queries = ReadImages(kImages, 41, 62);
  d.database_from = "images 1-20";
  d.queries_from = "images 41-62";
  return d;
}

ExperimentOptions SmallGrid() {
  ExperimentOptions o;
  o.features = {FeatureType::kOrb};
  o.resizes = {1, 4};
  o.verify = {true, false};
  o.eval.num_queries = 6;
  o.eval.seed = 3;
  o.build.threads = 2;
  o.num_pictures = 2;
  o.num_failures = 3;
  o.progress = false;
  return o;
}

nlohmann::json ReadJson(const std::string& path) {
  return nlohmann::json::parse(ReadFileToString(path));
}

TEST(ExperimentOptionsTest, ChecksTheGrid) {
  EXPECT_EQ(ExperimentOptions().Check(), "");
  EXPECT_EQ(ExperimentOptions().Grid().size(), 24u);  // the paper's grid x verification
  ExperimentOptions o;
  o.features.clear();
  EXPECT_NE(o.Check().find("`features` is empty"), std::string::npos);
  o = ExperimentOptions();
  o.resizes = {1, 2};
  EXPECT_NE(o.Check().find("`resize`"), std::string::npos);
  o = ExperimentOptions();
  o.crops = {CropMode::kNone, CropMode::kNone};
  EXPECT_NE(o.Check().find("`crop` repeats"), std::string::npos);
  o = ExperimentOptions();
  o.num_pictures = 21;
  EXPECT_NE(o.Check().find("`pictures`"), std::string::npos);
  o = ExperimentOptions();
  o.query.top_k = 0;
  EXPECT_NE(o.Check().find("`top_k`"), std::string::npos);
  const ExperimentSetting s{FeatureType::kSurf, CropMode::kChroma, 16, false};
  EXPECT_EQ(s.Name(), "surf_chroma_r16_noverify");
  EXPECT_EQ(s.Label(), "SURF chroma 1/16 unverified");
}

TEST(ExperimentTest, RunsTheGridResumesAndRefusesOtherArguments) {
  TempDir tmp;
  const std::string out = tmp.Path("exp");
  const GroundTruth truth = GroundTruth::FromMatchList(ReadMatchTruth(kTruth));
  const ExperimentData data = SmallData();
  const ExperimentOptions options = SmallGrid();
  const ExperimentSummary s = RunExperiment(data, truth, options, out);
  EXPECT_EQ(s.num_settings, 8);
  EXPECT_EQ(s.num_reused, 0);
  EXPECT_EQ(s.num_queries, 6);
  const nlohmann::json r = ReadJson(out + "/results.json");
  ASSERT_EQ(r["settings"].size(), 8u);
  std::set<int> ids;
  for (const nlohmann::json& setting : r["settings"]) {
    const nlohmann::json& e = setting["eval"];
    EXPECT_EQ(e["num_queries"], 6);
    EXPECT_EQ(setting["num_keyframes"], 20);
    EXPECT_EQ(e["verified"], setting["setting"]["verify"]);
    std::set<int> these;
    for (const nlohmann::json& q : e["queries"]) {
      these.insert(q["query_id"].get<int>());
      const int rank = q["first_correct_rank"];
      EXPECT_EQ(q["correct_at_1"].get<bool>(), rank == 1);
      EXPECT_GE(rank, 0);
      EXPECT_LE(rank, 10);
    }
    if (ids.empty()) ids = these;
    EXPECT_EQ(these, ids) << "every setting answers the same queries";
  }
  // Resizing shrinks the image store; the chroma crop does too.
  auto images = [&](int i) {
    return r["settings"][i]["eval"]["database_bytes"]["images"].get<uint64_t>();
  };
  EXPECT_LT(images(2), images(0));  // orb_none_r4 < orb_none_r1
  EXPECT_LT(images(4), images(0));  // orb_chroma_r1 < orb_none_r1
  // Pictures: match pictures for both crop modes, crop illustrations.
  EXPECT_FALSE(r["pictures"]["matches"].empty());
  EXPECT_FALSE(r["pictures"]["crops"].empty());
  for (const std::string& p : s.pictures) {
    EXPECT_GT(FileSize(out + "/" + p), 1000u) << p;
  }
  for (const nlohmann::json& m : r["pictures"]["matches"]) {
    if (m["crop"] == "none") {
      EXPECT_LE(m["num_lost"].get<int>(), m["num_matches"].get<int>());
    }
  }

  // Resume: everything finished is reused; the databases are not rebuilt.
  const auto built = fs::last_write_time(out + "/databases/orb_none_r1/manifest.json");
  fs::remove(out + "/settings/orb_chroma_r4_noverify.json");
  const ExperimentSummary again = RunExperiment(data, truth, options, out);
  EXPECT_EQ(again.num_reused, 7);
  EXPECT_EQ(fs::last_write_time(out + "/databases/orb_none_r1/manifest.json"), built);
  EXPECT_EQ(ReadJson(out + "/results.json")["settings"][7]["eval"]["queries"].size(), 6u);

  // A damaged result of a finished setting (the folder is ours):
  // CorruptDatabase naming the file and the field, never a JSON exception.
  const std::string setting_file = out + "/settings/orb_chroma_r4_noverify.json";
  WriteFileAtomic(setting_file, "{\"eval\": {\"num_queries\": 6}}\n");
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { RunExperiment(data, truth, options, out); },
                                          {setting_file, "eval.queries is missing"}));
  WriteFileAtomic(setting_file, "{ not json");
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { RunExperiment(data, truth, options, out); },
                                          {setting_file, "not valid JSON"}));
  fs::remove(setting_file);

  // Other arguments: refused, naming what differs, unless overwrite.
  ExperimentOptions other = options;
  other.eval.seed = 4;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { RunExperiment(data, truth, other, out); },
                                          "differ in 'eval'"));
  other.overwrite = true;
  other.resizes = {16};
  other.verify = {true};
  const ExperimentSummary fresh = RunExperiment(data, truth, other, out);
  EXPECT_EQ(fresh.num_reused, 0);
  EXPECT_EQ(fresh.num_settings, 2);
  EXPECT_FALSE(fs::exists(out + "/databases/orb_none_r1"));
}

// The grid's sequence and whole-image axes: settings of their own on the
// same database; with sequence evidence the report holds both answers (the
// frames' own ones equal the setting without it); the whole-image channel
// scores the answers (every ranked keyframe carries its similarity).
TEST(ExperimentTest, SequenceAndWholeImageAxes) {
  ExperimentOptions o = SmallGrid();
  o.resizes = {1};
  o.crops = {CropMode::kNone};
  o.verify = {true};
  o.sequence = {false, true};
  o.whole_image = {false, true};
  o.eval.all = true;
  ASSERT_EQ(o.Grid().size(), 4u);
  EXPECT_EQ(o.Grid()[3].Name(), "orb_none_r1_verify_seq_whole");
  EXPECT_EQ(o.Grid()[3].Label(), "ORB none 1 verified + sequence + whole image");
  TempDir tmp;
  const std::string out = tmp.Path("axes");
  const GroundTruth truth = GroundTruth::FromMatchList(ReadMatchTruth(kTruth));
  const ExperimentSummary s = RunExperiment(SmallData(), truth, o, out);
  EXPECT_EQ(s.num_settings, 4);
  const nlohmann::json r = ReadJson(out + "/results.json");
  ASSERT_EQ(r["settings"].size(), 4u);
  std::map<std::string, nlohmann::json> by_name;
  for (const nlohmann::json& setting : r["settings"])
    by_name[setting["setting"]["name"].get<std::string>()] = setting;
  const nlohmann::json& plain = by_name.at("orb_none_r1_verify")["eval"];
  const nlohmann::json& seq = by_name.at("orb_none_r1_verify_seq")["eval"];
  const nlohmann::json& whole = by_name.at("orb_none_r1_verify_whole")["eval"];
  EXPECT_TRUE(plain["single_frame"].is_null());
  ASSERT_TRUE(seq["single_frame"].is_object());
  EXPECT_EQ(seq["single_frame"]["num_correct"], plain["num_correct"]);
  EXPECT_GT(seq["sequence"]["decided"].get<int>(), 0);
  EXPECT_TRUE(by_name.at("orb_none_r1_verify_seq")["setting"]["sequence"].get<bool>());
  int with_similarity = 0;
  for (const nlohmann::json& q : whole["queries"]) {
    for (const nlohmann::json& k : q["result"]["ranked"])
      with_similarity += k["whole_image"].is_number();
  }
  EXPECT_GT(with_similarity, 0);
  for (const nlohmann::json& q : plain["queries"]) {
    for (const nlohmann::json& k : q["result"]["ranked"]) EXPECT_TRUE(k["whole_image"].is_null());
  }
  // One database serves the four settings.
  EXPECT_TRUE(fs::exists(out + "/databases/orb_none_r1"));
  size_t databases = 0;
  for (const auto& e : fs::directory_iterator(out + "/databases")) databases += e.is_directory();
  EXPECT_EQ(databases, 1u);
}

TEST(ExperimentTest, RefusesBadFoldersAndData) {
  TempDir tmp;
  const GroundTruth truth = GroundTruth::FromMatchList(ReadMatchTruth(kTruth));
  tmp.Write("busy/notes.txt", "mine");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { RunExperiment(SmallData(), truth, SmallGrid(), tmp.Path("busy")); },
      "holds no experiment"));
  EXPECT_TRUE(fs::exists(tmp.Path("busy/notes.txt")));
  tmp.Write("file", "x");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { RunExperiment(SmallData(), truth, SmallGrid(), tmp.Path("file")); }, "not a folder"));
  ExperimentData no_truth = SmallData();
  no_truth.queries = ReadImages(kImages, 1, 5);  // the truth lists queries 41-84
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { RunExperiment(no_truth, truth, SmallGrid(), tmp.Path("x")); }, "ground truth"));
  ExperimentData empty = SmallData();
  empty.database.clear();
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { RunExperiment(empty, truth, SmallGrid(), tmp.Path("y")); }, "no database frames"));
}

TEST(ExperimentReportTest, NeedsResults) {
  TempDir tmp;
  EXPECT_TRUE(ThrowsWith<NotFound>([&] { WriteExperimentReport(tmp.Path()); }, "no results.json"));
}

}  // namespace
}  // namespace placedb
