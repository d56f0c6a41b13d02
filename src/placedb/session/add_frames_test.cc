// PlaceDatabase::AddFrames: new frames get fresh ids (never one a removed
// keyframe had), or ids from an offset or from their file names; frames the
// database already holds are known by source path and content hash; the id
// summary (placedb info) and the manifest's "ids" entry. Issue #19, item 2.
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "placedb/builder/builder.h"
#include "placedb/dataset/image_folder.h"
#include "placedb/dataset/tum.h"
#include "placedb/session/place_database.h"
#include "placedb/feature/whole_image_model.h"
#include "placedb/storage/database.h"
#include "placedb/storage/whole_image_model_file.h"
#include "placedb/util/file_io.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
namespace fs = std::filesystem;
using testing_util::RtabmapImage;
using testing_util::ThrowsWith;

const std::string kImages = PLACEDB_DATA_DIR "/rtabmap_loop/images";
const std::string kTum = PLACEDB_DATA_DIR "/tum_fr3_office_mini";

class AddFramesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    BuildOptions options;
    options.threads = 2;
    options.progress = false;
    BuildDatabase(ListImageFolder(kImages, 1, 10), options, Dir(), "rtabmap 1..10");
  }
  std::string Dir() const { return tmp_.Path("db"); }
  // A folder `name` holding copies of rtabmap images `numbers`, named
  // 001.jpg, 002.jpg, ...: a new folder whose listing starts at 1 again.
  std::string NewFolder(const std::string& name, const std::vector<int>& numbers) const {
    const fs::path dir = tmp_.Path(name);
    fs::create_directories(dir);
    for (size_t i = 0; i < numbers.size(); ++i) {
      char file[32];
      std::snprintf(file, sizeof(file), "%03zu.jpg", i + 1);
      fs::copy_file(RtabmapImage(numbers[i]), dir / file, fs::copy_options::overwrite_existing);
    }
    return dir.string();
  }
  static Frame FrameAt(const std::string& path, int position) {
    Frame f;
    f.id = position;
    f.image_path = path;
    return f;
  }

  testing_util::TempDir tmp_;
};

// The finding: a new folder's frames are 1, 2, ... by position, which the
// database holds already. They get the ids after the largest instead, and
// TUM frames keep their poses and timestamps.
TEST_F(AddFramesTest, NewFramesGetFreshIdsAndKeepTheirPoses) {
  PlaceDatabase db = PlaceDatabase::Open(Dir());
  KeyframeIdSummary ids = db.id_summary();
  EXPECT_EQ(ids.count, 10u);
  EXPECT_EQ(ids.first, 1);
  EXPECT_EQ(ids.last, 10);
  EXPECT_EQ(ids.next_free, 11);
  ASSERT_TRUE(ids.removed.has_value());
  EXPECT_EQ(*ids.removed, 0u);

  const AddReport folder = db.AddFrames(ListImageFolder(NewFolder("new", {50, 51, 52}), 1, 0));
  EXPECT_EQ(folder.added, 3u);
  EXPECT_EQ(folder.skipped, 0u);
  EXPECT_EQ(folder.ids, (std::vector<int32_t>{11, 12, 13}));
  EXPECT_EQ(folder.first_id, 11);
  EXPECT_EQ(folder.last_id, 13);
  EXPECT_EQ(db.FindKeyframe(12)->source, tmp_.Path("new") + "/002.jpg");

  const std::vector<Frame> tum = ReadTumSequence(kTum, TumOptions());
  ASSERT_EQ(tum.size(), 4u);
  const AddReport r = db.AddFrames(tum);
  EXPECT_EQ(r.ids, (std::vector<int32_t>{14, 15, 16, 17}));
  int with_pose = 0;
  for (size_t i = 0; i < tum.size(); ++i) {
    const std::optional<Keyframe> k = db.FindKeyframe(r.ids[i]);
    ASSERT_TRUE(k.has_value());
    EXPECT_EQ(k->timestamp, tum[i].timestamp);
    ASSERT_EQ(k->pose.has_value(), tum[i].pose.has_value()) << i;
    if (!k->pose) continue;
    ++with_pose;
    EXPECT_EQ(k->pose->translation, tum[i].pose->translation);
    EXPECT_EQ(k->pose->rotation.coeffs(), tum[i].pose->rotation.coeffs());
  }
  EXPECT_EQ(with_pose, 3);
  db.Save();

  // A removed keyframe's id is not given again, also after a reopen.
  ASSERT_TRUE(db.Remove(17));
  ASSERT_TRUE(db.Remove(3));
  EXPECT_EQ(*db.id_summary().removed, 2u);
  db.Save();
  PlaceDatabase reopened = PlaceDatabase::Open(Dir());
  ids = reopened.id_summary();
  EXPECT_EQ(ids.count, 15u);
  EXPECT_EQ(ids.first, 1);
  EXPECT_EQ(ids.last, 16);
  EXPECT_EQ(ids.next_free, 18);
  EXPECT_EQ(*ids.removed, 2u);
  const AddReport more = reopened.AddFrames(ListImageFolder(NewFolder("more", {60}), 1, 0));
  EXPECT_EQ(more.ids, (std::vector<int32_t>{18}));
  const nlohmann::json info = nlohmann::json::parse(reopened.info_json());
  EXPECT_EQ(info["ids"]["next_free"], 19);
  EXPECT_EQ(info["ids"]["removed"], 2);
  EXPECT_EQ(info["ids"]["first"], 1);
  EXPECT_EQ(info["ids"]["last"], 18);
  EXPECT_EQ(info["ids"]["count"], 16);
}

// --skip-existing: the same source (path and content) is left out and
// counted; the same path with other content is a new keyframe; without it,
// an existing frame is an error that changes nothing.
TEST_F(AddFramesTest, ExistingFramesAreKnownBySourceAndContent) {
  PlaceDatabase db = PlaceDatabase::Open(Dir());
  const std::string dir = NewFolder("new", {50, 51, 52, 53});
  db.AddFrames(ListImageFolder(dir, 1, 2));  // 001, 002
  // The whole folder again, overlapping: 2 held, 2 new.
  AddOptions skip;
  skip.skip_existing = true;
  const std::vector<Frame> all = ListImageFolder(dir, 1, 0);
  AddReport r = db.AddFrames(all, skip);
  EXPECT_EQ(r.added, 2u);
  EXPECT_EQ(r.skipped, 2u);
  EXPECT_EQ(r.skipped_by_path, 0u);
  EXPECT_EQ(r.ids, (std::vector<int32_t>{11, 12, 13, 14}));
  EXPECT_TRUE(r.changed_sources.empty());
  // Built keyframes are known too (their sources hashed at build).
  r = db.AddFrames(ListImageFolder(kImages, 4, 6), skip);
  EXPECT_EQ(r.added, 0u);
  EXPECT_EQ(r.skipped, 3u);
  EXPECT_EQ(r.ids, (std::vector<int32_t>{4, 5, 6}));
  // Without skip_existing: an error naming the keyframe, nothing added.
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddFrames(all); }, "is already keyframe 11 of"));
  EXPECT_EQ(db.size(), 14u);

  // 003.jpg now holds another image: same path, new content, added.
  fs::copy_file(RtabmapImage(70), dir + "/003.jpg", fs::copy_options::overwrite_existing);
  r = db.AddFrames(all, skip);
  EXPECT_EQ(r.added, 1u);
  EXPECT_EQ(r.skipped, 3u);
  EXPECT_EQ(r.ids[2], 15);
  ASSERT_EQ(r.changed_sources.size(), 1u);
  EXPECT_EQ(r.changed_sources[0], dir + "/003.jpg");
  EXPECT_NE(db.FindKeyframe(15)->source_hash, db.FindKeyframe(13)->source_hash);
  EXPECT_EQ(db.FindKeyframe(13)->source, db.FindKeyframe(15)->source);

  // One image given twice is added once.
  const std::string twice = NewFolder("twice", {80});
  std::vector<Frame> frames = {FrameAt(twice + "/001.jpg", 1), FrameAt(twice + "/001.jpg", 2)};
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddFrames(frames); },
                                          "the same image as an earlier frame given"));
  r = db.AddFrames(frames, skip);
  EXPECT_EQ(r.added, 1u);
  EXPECT_EQ(r.repeated, 1u);
  EXPECT_EQ(r.ids, (std::vector<int32_t>{16, 16}));

  // The hashes are saved: a reopened database knows the frames.
  db.Save();
  PlaceDatabase reopened = PlaceDatabase::Open(Dir());
  r = reopened.AddFrames(all, skip);
  EXPECT_EQ(r.added, 0u);
  EXPECT_EQ(r.skipped, 4u);
}

// A database an earlier placedb wrote: no source hashes (0), no "ids" entry,
// no whole-image channel.
// Frames are known by path alone; the next free id follows the largest;
// removals are "not recorded" until the next save starts counting.
TEST_F(AddFramesTest, DatabasesWithoutHashesFallBackToThePath) {
  {
    const Database built = Database::Load(Dir());
    Database old(built.feature_type(), built.descriptor_bytes());
    for (size_t i = 0; i < built.size(); ++i) {
      Keyframe k = built.keyframe(i);
      ASSERT_NE(k.source_hash, 0u);
      k.source_hash = 0;
      old.AddKeyframe(k, built.Features(i));
    }
    old.info() = built.info();
    old.info().erase("ids");
    // Nor a whole-image channel: no section, no settings for it.
    old.info()["settings"]["features"].erase("whole_image");
    old.Save(Dir());
  }
  PlaceDatabase db = PlaceDatabase::Open(Dir());
  EXPECT_EQ(db.whole_image_dims(), 0);
  KeyframeIdSummary ids = db.id_summary();
  EXPECT_EQ(ids.next_free, 11);
  EXPECT_FALSE(ids.removed.has_value());
  EXPECT_TRUE(nlohmann::json::parse(db.info_json())["ids"]["removed"].is_null());
  AddOptions skip;
  skip.skip_existing = true;
  const AddReport r = db.AddFrames(ListImageFolder(kImages, 9, 12), skip);
  EXPECT_EQ(r.added, 2u);
  EXPECT_EQ(r.skipped, 2u);
  EXPECT_EQ(r.skipped_by_path, 2u);
  EXPECT_EQ(r.ids, (std::vector<int32_t>{9, 10, 11, 12}));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddFrames(ListImageFolder(kImages, 1, 1)); },
                                          "that keyframe has no content hash"));
  ASSERT_TRUE(db.Remove(2));
  db.Save();
  ids = PlaceDatabase::Open(Dir()).id_summary();
  ASSERT_TRUE(ids.removed.has_value());
  EXPECT_EQ(*ids.removed, 1u);
  EXPECT_FALSE(ids.removed_since.empty());
  EXPECT_EQ(ids.next_free, 13);
}

// The manifest's "ids" entry is read strictly: a damaged one is a corrupt
// database, named; a next_free below the largest id is overruled by it.
TEST_F(AddFramesTest, DamagedIdsEntriesAreCorruptDatabases) {
  const std::string path = Dir() + "/manifest.json";
  const nlohmann::json manifest = nlohmann::json::parse(ReadFileToString(path));
  for (const nlohmann::json& bad :
       {nlohmann::json("x"),
        nlohmann::json{{"next_free", "12"}, {"removed", 0}, {"removed_since", ""}},
        nlohmann::json{{"next_free", 0}, {"removed", 0}, {"removed_since", ""}},
        nlohmann::json{{"next_free", 4294967296}, {"removed", 0}, {"removed_since", ""}},
        nlohmann::json{{"next_free", 12}, {"removed", -1}, {"removed_since", ""}},
        nlohmann::json{{"next_free", 12}, {"removed", 1.5}, {"removed_since", ""}},
        nlohmann::json{{"next_free", 12}, {"removed", 0}}}) {
    nlohmann::json m = manifest;
    m["ids"] = bad;
    WriteFileAtomic(path, m.dump());
    EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { PlaceDatabase::Open(Dir()); }, "ids"))
        << bad.dump();
  }
  nlohmann::json m = manifest;
  m["ids"]["next_free"] = 2;
  WriteFileAtomic(path, m.dump());
  EXPECT_EQ(PlaceDatabase::Open(Dir()).id_summary().next_free, 11);
}

// id_offset: the k-th frame given gets offset + k - 1; ids_from_names: the
// file name's number. Taken, repeated or impossible ids and names that are
// not numbers are refused before anything changes.
TEST_F(AddFramesTest, IdsFromAnOffsetOrFromNames) {
  PlaceDatabase db = PlaceDatabase::Open(Dir());
  const std::string dir = NewFolder("new", {50, 51, 52});
  AddOptions offset;
  offset.id_offset = 100;
  AddReport r = db.AddFrames(ListImageFolder(dir, 2, 3), offset);
  EXPECT_EQ(r.ids, (std::vector<int32_t>{100, 101}));
  offset.id_offset = 10;  // 10 is keyframe 10's
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddFrames(ListImageFolder(dir, 1, 1), offset); },
                                          "would get id 10, which is taken by the keyframe of"));
  offset.id_offset = INT32_MAX;
  std::vector<Frame> two = {FrameAt(RtabmapImage(60), 1), FrameAt(RtabmapImage(61), 2)};
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddFrames(two, offset); },
                                          "above the largest, 2^31 - 1"));
  EXPECT_EQ(db.size(), 12u);
  EXPECT_EQ(db.id_summary().next_free, 102);

  AddOptions names;
  names.ids_from_names = true;
  const std::string named = tmp_.Path("named");
  fs::create_directories(named);
  auto copy = [&](const std::string& name, int image) {
    fs::copy_file(RtabmapImage(image), named + "/" + name, fs::copy_options::overwrite_existing);
    return FrameAt(named + "/" + name, 1);
  };
  r = db.AddFrames({copy("042.jpg", 42), copy("0077", 43), copy("43.png", 44)}, names);
  EXPECT_EQ(r.ids, (std::vector<int32_t>{42, 77, 43}));
  for (const std::string bad :
       {"frame_042.jpg", "-4.jpg", "1e3.png", "0.jpg", "000.jpg", "2147483648.jpg",
        "99999999999999999999.jpg", " 42.jpg", "42 .jpg", "４２.jpg", ".jpg"}) {
    const Frame f = copy(bad, 45);
    EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddFrames({f}, names); },
                                            "cannot take an id from the file name"))
        << bad;
  }
  Frame from_bag = FrameAt("bag:x.bag:/camera", 1);
  from_bag.load = [] { return cv::imread(RtabmapImage(46)); };
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddFrames({from_bag}, names); },
                                          "has no file name to take an id from"));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] {
        db.AddFrames({copy("050.jpg", 47), copy("50.png", 48)}, names);
      },
      "which another frame given gets too"));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.AddFrames({copy("5.jpg", 49)}, names); },
                                          "would get id 5, which is taken"));
  names.id_offset = 3;
  EXPECT_TRUE(
      ThrowsWith<InvalidArgument>([&] { db.AddFrames({copy("51.jpg", 49)}, names); }, "not both"));
  // A bag frame (no file) is hashed by its pixels, and known again.
  AddOptions skip;
  skip.skip_existing = true;
  r = db.AddFrames({from_bag}, skip);
  EXPECT_EQ(r.added, 1u);
  EXPECT_NE(db.FindKeyframe(r.ids[0])->source_hash, 0u);
  r = db.AddFrames({from_bag}, skip);
  EXPECT_EQ(r.skipped, 1u);
}

// A database with the HOG whole-image channel: the build fits its model
// and names it in the manifest; a session projects queries and added
// frames with it (a frame's own row is what the build stored for it), its
// similarities serve the whole-map sequence, and a missing, damaged or
// mismatched model file is CorruptDatabase at the open.
TEST(HogChannelTest, BuildAddQueryAndADamagedModel) {
  testing_util::TempDir tmp;
  const std::string dir = tmp.Path("db");
  BuildOptions options;
  options.threads = 2;
  options.progress = false;
  options.features.whole_image.kind = WholeImageKind::kHog;
  BuildDatabase(ListImageFolder(kImages, 1, 20), options, dir, "rtabmap 1..20");
  {
    PlaceDatabase db = PlaceDatabase::Open(dir);
    EXPECT_EQ(db.whole_image_dims(), 512);
    EXPECT_EQ(db.build_options().features.whole_image.hog_height, 48);  // 512 x 384 frames
    const FeatureSet q = db.Extract(cv::imread(RtabmapImage(7)));
    ASSERT_EQ(q.whole_image.type(), CV_8SC1);
    ASSERT_EQ(q.whole_image.cols, 512);
    const std::vector<float> s = db.WholeImageSimilarities(q);
    ASSERT_EQ(s.size(), 20u);
    EXPECT_NEAR(s[6], 1.0f, 1e-5);  // keyframe 7 is this image
    EXPECT_EQ(std::max_element(s.begin(), s.end()) - s.begin(), 6);
    db.AddFrames(ListImageFolder(kImages, 50, 51));
    const FeatureSet added = db.KeyframeFeatures(21);
    const FeatureSet again = db.Extract(cv::imread(RtabmapImage(50)));
    EXPECT_EQ(cv::norm(added.whole_image, again.whole_image, cv::NORM_INF), 0);
    std::vector<float> sims;
    db.Query(cv::imread(RtabmapImage(51)), QueryOptions(), &sims);
    ASSERT_EQ(sims.size(), 22u);
    EXPECT_NEAR(sims[21], 1.0f, 1e-5);
  }
  const std::string model = dir + "/whole_image_model.bin";
  const std::string bytes = ReadFileToString(model);
  fs::remove(model);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { PlaceDatabase::Open(dir); }, "is missing"));
  std::string damaged = bytes;
  damaged[200] ^= 1;
  WriteFileAtomic(model, damaged);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { PlaceDatabase::Open(dir); }, "whole_image_model.bin"));
  // A valid model of another shape than the manifest's settings.
  std::vector<cv::Mat> raw;
  for (int i = 1; i <= 4; ++i) raw.push_back(ComputeHogRaw(cv::imread(RtabmapImage(i)), 64, 48));
  SaveWholeImageModel(WholeImageModel::Fit(raw, 64, 48, 256), model);
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { PlaceDatabase::Open(dir); }, "the manifest's settings"));
  WriteFileAtomic(model, bytes);
  EXPECT_NO_THROW(PlaceDatabase::Open(dir));
}

}  // namespace
}  // namespace placedb
