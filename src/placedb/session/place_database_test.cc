// The session API as a client uses it: open a built database from disk and
// ask where images were taken.
#include "placedb/session/place_database.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>
#include <thread>

#include "placedb/builder/builder.h"
#include "placedb/dataset/image_folder.h"
#include "placedb/query/query.h"
#include "placedb/session/storage_view.h"
#include "placedb/util/file_io.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
namespace fs = std::filesystem;
using testing_util::RtabmapImage;
using testing_util::ThrowsWith;

const std::string kImages = PLACEDB_DATA_DIR "/rtabmap_loop/images";

// A database of rtabmap images 1..40 (ORB, no crop), built once.
class PlaceDatabaseTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    tmp_ = new fs::path(fs::temp_directory_path() /
                        ("placedb_place_database_test_" + std::to_string(::getpid())));
    fs::remove_all(*tmp_);
    BuildOptions options;
    options.threads = 2;
    options.progress = false;
    BuildDatabase(ListImageFolder(kImages, 1, 40), options, Dir(), "rtabmap 1..40");
  }
  static void TearDownTestSuite() {
    fs::remove_all(*tmp_);
    delete tmp_;
  }
  static std::string Dir() { return (*tmp_ / "db").string(); }

  static fs::path* tmp_;
};
fs::path* PlaceDatabaseTest::tmp_ = nullptr;

// Open reads the settings back from the manifest; a query image gives a true
// match with its pose field, stored image and source; the same features
// given directly give the same answer.
TEST_F(PlaceDatabaseTest, OpenAndQuery) {
  const PlaceDatabase db = PlaceDatabase::Open(Dir());
  EXPECT_EQ(db.size(), 40u);
  EXPECT_EQ(db.feature_type(), FeatureType::kOrb);
  EXPECT_EQ(db.directory(), Dir());
  EXPECT_EQ(db.build_options().crop, CropMode::kNone);
  EXPECT_EQ(db.build_options().resize, 1);
  EXPECT_EQ(db.extractor_options().orb.max_features, OrbOptions().max_features);
  EXPECT_EQ(StorageView(db).pool(), nullptr);
  const cv::Mat image = cv::imread(RtabmapImage(42));
  const QueryResult r = db.Query(image);
  ASSERT_NE(r.best(), nullptr);
  EXPECT_TRUE((std::set<int>{1, 2, 3, 4}).count(r.best()->keyframe_id)) << r.best()->keyframe_id;
  EXPECT_GT(r.times.extract_ms, 0.0);
  EXPECT_GE(r.times.total_ms, r.times.extract_ms + r.times.match_ms);
  EXPECT_TRUE(fs::exists(r.best()->stored_image)) << r.best()->stored_image;
  EXPECT_EQ(r.best()->source, RtabmapImage(r.best()->keyframe_id));
  EXPECT_FALSE(r.best()->pose.has_value());  // image folders have no poses
  const std::optional<Keyframe> k = db.FindKeyframe(r.best()->keyframe_id);
  ASSERT_TRUE(k.has_value());
  EXPECT_EQ(db.StoredImagePath(*k), r.best()->stored_image);
  EXPECT_FALSE(db.FindKeyframe(41));
  const QueryResult same = db.Query(db.Extract(image));
  EXPECT_EQ(same.ranked, r.ranked);
  EXPECT_EQ(same.times.extract_ms, 0.0);
}

// A session with a pool answers as a single-threaded one; queries from two
// threads at once on one session are safe and give the serial answers.
TEST_F(PlaceDatabaseTest, ThreadsDoNotChangeTheAnswer) {
  const PlaceDatabase one = PlaceDatabase::Open(Dir());
  OpenOptions options;
  options.threads = 0;  // one per core
  const PlaceDatabase many = PlaceDatabase::Open(Dir(), options);
  ASSERT_NE(StorageView(many).pool(), nullptr);
  std::vector<FeatureSet> features;
  std::vector<QueryResult> expected;
  for (int q = 41; q <= 84; q += 3) {
    features.push_back(one.Extract(cv::imread(RtabmapImage(q))));
    expected.push_back(one.Query(features.back()));
    EXPECT_EQ(many.Query(features.back()).ranked, expected.back().ranked) << "query " << q;
  }
  std::vector<std::vector<QueryResult>> got(2);
  std::vector<std::thread> threads;
  for (int t = 0; t < 2; ++t) {
    threads.emplace_back([&, t] {
      for (const FeatureSet& f : features) got[t].push_back(many.Query(f));
    });
  }
  for (auto& t : threads) t.join();
  for (int t = 0; t < 2; ++t) {
    ASSERT_EQ(got[t].size(), expected.size());
    for (size_t i = 0; i < expected.size(); ++i) EXPECT_EQ(got[t][i].ranked, expected[i].ranked);
  }
}

// Partitions opened from disk (as N worker processes would), each queried
// with ForPartition options, merge into the whole database's answer, with
// the whole-image channel scoring (each standardises over the file's rows).
TEST_F(PlaceDatabaseTest, PartitionsOpenedFromDiskMergeIntoTheWholeAnswer) {
  const PlaceDatabase whole = PlaceDatabase::Open(Dir());
  for (const PartitionScheme scheme :
       {PartitionScheme::kContiguous, PartitionScheme::kInterleaved}) {
    std::vector<PlaceDatabase> parts;
    for (int p = 0; p < 3; ++p) {
      OpenOptions o;
      o.subset = KeyframeSubset::Partition(p, 3, scheme);
      parts.push_back(PlaceDatabase::Open(Dir(), o));
    }
    EXPECT_EQ(parts[0].size() + parts[1].size() + parts[2].size(), 40u);
    const QueryOptions options;
    for (int q = 41; q <= 84; q += 5) {
      const FeatureSet f = whole.Extract(cv::imread(RtabmapImage(q)));
      std::vector<QueryResult> partial;
      for (const PlaceDatabase& p : parts) partial.push_back(p.Query(f, options.ForPartition()));
      const QueryResult merged = MergeQueryResults(partial, options);
      const QueryResult expected = whole.Query(f, options);
      EXPECT_EQ(merged.ranked, expected.ranked) << "query " << q;
      EXPECT_EQ(merged.matched, expected.matched);
    }
  }
}

// QueryAmong restricts a query to given keyframe indices; an id subset opens
// just those keyframes and answers alike.
TEST_F(PlaceDatabaseTest, RestrictionsAndIdSubsets) {
  const PlaceDatabase db = PlaceDatabase::Open(Dir());
  const cv::Mat image = cv::imread(RtabmapImage(60));  // true matches 18..22
  const QueryResult among = db.QueryAmong(image, {1, 2, 3, 21, 22});
  EXPECT_EQ(among.num_examined, 5u);
  ASSERT_NE(among.best(), nullptr);
  EXPECT_TRUE(among.best()->keyframe_id == 21 || among.best()->keyframe_id == 22);
  OpenOptions o;
  o.subset = KeyframeSubset::Ids({1, 2, 3, 21, 22});
  const PlaceDatabase subset = PlaceDatabase::Open(Dir(), o);
  EXPECT_EQ(subset.size(), 5u);
  EXPECT_EQ(subset.Query(image).ranked, among.ranked);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.QueryAmong(image, {41}); }, "no keyframe 41"));
}

// Bad input to a session: another feature type than expected, images that
// are not 8-bit frames, bad open options.
TEST_F(PlaceDatabaseTest, BadInputIsAClearError) {
  OpenOptions surf;
  surf.expected_features = FeatureType::kSurf;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { PlaceDatabase::Open(Dir(), surf); },
                                          {"holds orb features but surf"}));
  EXPECT_TRUE(ThrowsWith<NotFound>([&] { PlaceDatabase::Open(Dir() + "/no_such_db"); },
                                   {"no database at", "no_such_db"}));
  const PlaceDatabase db = PlaceDatabase::Open(Dir());
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.Query(cv::Mat()); }, "empty"));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { db.Query(cv::Mat(100, 100, CV_16UC1, cv::Scalar(0))); }, "8-bit"));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { db.Query(cv::Mat(100, 100, CV_8UC2, cv::Scalar(0))); }, "8-bit"));
  // A tiny or flat frame is no error: no match.
  EXPECT_FALSE(db.Query(cv::Mat(5, 5, CV_8UC3, cv::Scalar(10, 20, 30))).matched);
  EXPECT_FALSE(db.Query(cv::Mat(384, 512, CV_8UC1, cv::Scalar(90))).matched);
  OpenOptions bad;
  bad.threads = -1;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { PlaceDatabase::Open(Dir(), bad); },
                                          "threads must be in [0, 1024]"));
  QueryOptions q;
  q.top_k = 0;
  EXPECT_TRUE(
      ThrowsWith<InvalidArgument>([&] { db.Query(cv::imread(RtabmapImage(42)), q); }, "top_k"));
}

// A manifest whose feature settings disagree with the stored descriptors (a
// tampered or mixed-up database) is refused when opened.
TEST_F(PlaceDatabaseTest, ManifestSettingsMustAgreeWithTheKeyframes) {
  const fs::path copy = *tmp_ / "tampered";
  fs::remove_all(copy);
  fs::create_directories(copy);
  for (const auto& e : fs::directory_iterator(Dir())) {
    if (e.is_regular_file()) fs::copy_file(e.path(), copy / e.path().filename());
  }
  const std::string manifest_path = (copy / "manifest.json").string();
  const nlohmann::json original = nlohmann::json::parse(ReadFileToString(manifest_path));
  nlohmann::json m = original;
  m["settings"]["features"]["type"] = "surf";
  m["feature_type"] = "orb";
  WriteFileAtomic(manifest_path, m.dump());
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { PlaceDatabase::Open(copy.string()); },
                                          "the manifest's feature settings say surf"));
  m = original;
  m["settings"]["resize"] = "4";
  WriteFileAtomic(manifest_path, m.dump());
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { PlaceDatabase::Open(copy.string()); },
                                          "settings.resize is not a whole number"));
  // The whole-image channel: settings that say none (or another size) with
  // a file that holds it are a corrupt database, and the reverse.
  EXPECT_EQ(original["whole_image_dims"], 512);  // the default HOG channel
  m = original;
  m["settings"]["features"]["whole_image"]["enabled"] = false;
  WriteFileAtomic(manifest_path, m.dump());
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>(
      [&] { PlaceDatabase::Open(copy.string()); },
      "settings have no whole-image channel but the keyframes hold rows of 512 values"));
  m = original;
  m["settings"]["features"]["whole_image"]["kind"] = "thumbnail";  // 32 x 24
  WriteFileAtomic(manifest_path, m.dump());
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { PlaceDatabase::Open(copy.string()); },
                                          "give whole-image rows of 768 values"));
  m = original;
  m.erase("whole_image_dims");
  WriteFileAtomic(manifest_path, m.dump());
  EXPECT_TRUE(ThrowsWith<CorruptDatabase>([&] { PlaceDatabase::Open(copy.string()); },
                                          "disagree on the whole-image channel"));
  WriteFileAtomic(manifest_path, original.dump());
  EXPECT_EQ(PlaceDatabase::Open(copy.string()).whole_image_dims(), 512);
  EXPECT_NO_THROW(PlaceDatabase::Open(copy.string()));
}

// Small cameras: a database and queries at 160x120 (the frames resized as
// they are read). Upscaling small frames for extraction (the default) finds
// more than twice the features and keeps recall@1 (measured 0.977 with,
// 0.909 without).
TEST(PlaceDatabaseSmallFramesTest, UpscalingSmallFramesKeepsRecall) {
  const fs::path tmp =
      fs::temp_directory_path() / ("placedb_place_database_small_" + std::to_string(::getpid()));
  fs::remove_all(tmp);
  std::vector<Frame> train = ListImageFolder(kImages, 1, 40);
  std::vector<Frame> queries = ListImageFolder(kImages, 41, 84);
  ResizeFramesTo(&train, {160, 120});
  ResizeFramesTo(&queries, {160, 120});
  std::map<int, std::set<int>> truth;
  {
    std::ifstream in(PLACEDB_DATA_DIR "/rtabmap_loop/ground_truth.csv");
    std::string line;
    while (std::getline(in, line)) {
      if (line.empty() || line[0] == '#') continue;
      const size_t comma = line.find(',');
      std::istringstream ids(line.substr(comma + 1));
      for (int id; ids >> id;) truth[std::stoi(line.substr(0, comma))].insert(id);
    }
  }
  int correct[2] = {0, 0};
  size_t features[2] = {0, 0};
  for (int upscale : {0, 1}) {
    BuildOptions options;
    options.threads = 2;
    options.progress = false;
    if (!upscale) options.features.upscale_below = 0;
    const std::string dir = (tmp / ("db" + std::to_string(upscale))).string();
    BuildDatabase(train, options, dir, "rtabmap 1..40 at 160x120");
    const PlaceDatabase db = PlaceDatabase::Open(dir);
    EXPECT_EQ(db.extractor_options().upscale_below, options.features.upscale_below);
    EXPECT_EQ(StorageView(db).database().keyframe(0).original_size, cv::Size(160, 120));
    features[upscale] = StorageView(db).database().num_features();
    for (const Frame& q : queries) {
      const QueryResult r = db.Query(LoadFrameImage(q));
      if (!r.ranked.empty() && truth[q.id].count(r.ranked[0].keyframe_id)) ++correct[upscale];
    }
  }
  fs::remove_all(tmp);
  std::printf("160x120: %zu features / R@1 %d/44 upscaled, %zu / %d/44 not\n", features[1],
              correct[1], features[0], correct[0]);
  EXPECT_GT(features[1], 2 * features[0]);
  EXPECT_GE(correct[1], correct[0]);
  EXPECT_GE(correct[1], 42);
}

// Every file under `root` (symlinks as "-> target"), path -> content.
std::map<std::string, std::string> Tree(const fs::path& root) {
  std::map<std::string, std::string> out;
  for (auto it = fs::recursive_directory_iterator(root); it != fs::recursive_directory_iterator();
       ++it) {
    const fs::path p = it->path();
    const std::string key = p.lexically_relative(root).string();  // links not resolved
    if (fs::is_symlink(fs::symlink_status(p))) {
      out[key] = "-> " + fs::read_symlink(p).string();
    } else if (fs::is_regular_file(fs::symlink_status(p))) {
      out[key] = ReadFileToString(p.string());
    } else {
      out[key] = "(folder)";
    }
  }
  return out;
}

// The mutation family of the images/ folder (issue 46): a symlink out of the
// database (to a folder, a file, nothing), links inside it, a file in its
// place, a user's files and a killed writer's debris beside the stored
// images. Reads (open, query, verify, the keyframe table) change nothing
// anywhere; a writer (remove and save, add) removes only placedb's own debris
// in a real images/ folder, never anything through a link or outside the
// database, and refuses to store an image through a link.
TEST(PlaceDatabaseFolderTest, MutatedImagesFolders) {
  testing_util::TempDir tmp;
  BuildOptions options;
  options.threads = 2;
  options.progress = false;
  options.index = IndexKind::kNone;
  const std::vector<Frame> frames = ListImageFolder(kImages, 1, 4);
  BuildDatabase(frames, options, tmp.Path("original"), "rtabmap 1..4");
  const cv::Mat query = cv::imread(RtabmapImage(2));
  const std::string dead_temp = "000003.png.tmp.99999999.1";
  const std::string live_temp = "000003.png.tmp." + std::to_string(::getpid()) + ".9";
  for (int layout = 0; layout < 7; ++layout) {
    const fs::path root = tmp.Path("case" + std::to_string(layout));
    const fs::path db = root / "db", images = db / "images", outside = root / "outside";
    fs::create_directories(root);
    fs::copy(tmp.Path("original"), db, fs::copy_options::recursive);
    fs::create_directories(outside);
    fs::copy(images, outside / "copies");
    WriteFileAtomic((outside / "holiday.png").string(), "mine");
    WriteFileAtomic((outside / "000077.png").string(), "mine too");
    bool linked = true;  // images/ is no folder of the database's
    switch (layout) {
      case 0:  // a link to a folder holding the stored images and more
        fs::remove_all(images);
        fs::copy(outside / "copies", outside / "shared");
        fs::copy_file(outside / "holiday.png", outside / "shared" / "holiday.png");
        fs::copy_file(outside / "000077.png", outside / "shared" / "000077.png");
        fs::create_directory_symlink(outside / "shared", images);
        break;
      case 1:  // a link to a file
        fs::remove_all(images);
        fs::create_symlink(outside / "holiday.png", images);
        break;
      case 2:  // a link to nothing
        fs::remove_all(images);
        fs::create_symlink(outside / "gone", images);
        break;
      case 3:  // a file
        fs::remove_all(images);
        WriteFileAtomic(images.string(), "a file");
        break;
      default:  // a real folder with links, a user's file and debris in it
        linked = false;
        fs::create_symlink(outside / "000077.png", images / "000077.png");
        if (layout >= 5) {
          fs::remove(images / "000001.png");
          fs::create_symlink(outside / "holiday.png", images / "000001.png");
        }
        WriteFileAtomic((images / "holiday.png").string(), "mine, inside");
        WriteFileAtomic((images / dead_temp).string(), "debris");
        WriteFileAtomic((images / live_temp).string(), "a live writer's");
        if (layout == 6) WriteFileAtomic((images / "000088.png").string(), "an orphan");
        break;
    }
    const std::map<std::string, std::string> before = Tree(root);
    {
      const PlaceDatabase reader = PlaceDatabase::Open(db.string());
      EXPECT_FALSE(reader.Query(query).ranked.empty()) << layout;
      reader.Verify();
      OpenOptions table;
      table.keyframe_table = true;
      EXPECT_EQ(PlaceDatabase::Open(db.string(), table).size(), 4u);
    }
    EXPECT_EQ(Tree(root), before) << "a read changed the files, layout " << layout;
    {
      PlaceDatabase writer = PlaceDatabase::Open(db.string());
      ASSERT_TRUE(writer.Remove(1));
      writer.Save();
    }
    std::map<std::string, std::string> after = Tree(root);
    for (const auto& [path, content] : before) {
      if (path.rfind("outside", 0) == 0) {
        EXPECT_EQ(after[path], content) << layout << ": " << path;  // nothing outside, ever
      }
    }
    if (linked) {
      for (const auto& [path, content] : before) {
        if (path.rfind("db/images", 0) == 0) {
          EXPECT_EQ(after[path], content) << layout << path;
        }
      }
      const Frame fifth = ListImageFolder(kImages, 5, 5)[0];
      PlaceDatabase adder = PlaceDatabase::Open(db.string());
      EXPECT_TRUE(
          ThrowsWith<InvalidArgument>([&] { adder.AddFrames({fifth}, AddOptions(), false); },
                                      "placedb stores keyframe images only in a real "
                                      "folder of the database"))
          << layout;
      EXPECT_EQ(adder.size(), 3u);
    } else {
      // The removed keyframe's image goes (unless it is a link: links stay);
      // so do a dead writer's temporary file and an orphan of placedb's
      // naming; the user's file, the live writer's, and links stay.
      EXPECT_EQ(after.count("db/images/000001.png"), layout >= 5 ? 1u : 0u) << layout;
      EXPECT_EQ(after.count("db/images/" + dead_temp), 0u) << layout;
      EXPECT_EQ(after.count("db/images/000088.png"), 0u) << layout;
      EXPECT_EQ(after["db/images/" + live_temp], "a live writer's") << layout;
      EXPECT_EQ(after["db/images/holiday.png"], "mine, inside") << layout;
      EXPECT_EQ(after.count("db/images/000077.png"), 1u) << layout;
      EXPECT_EQ(after["db/images/000002.png"], before.at("db/images/000002.png")) << layout;
    }
  }
}

}  // namespace
}  // namespace placedb
