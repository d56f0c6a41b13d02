// Online mapping: keyframes added and removed while queries run, saved and
// reopened.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <thread>

#include "placedb/builder/builder.h"
#include "placedb/dataset/image_folder.h"
#include "placedb/feature/whole_image.h"
#include "placedb/query/query.h"
#include "placedb/session/place_database.h"
#include "placedb/session/storage_view.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
namespace fs = std::filesystem;
using testing_util::RtabmapImage;
using testing_util::ThrowsWith;

const std::string kImages = PLACEDB_DATA_DIR "/rtabmap_loop/images";

class OnlineTest : public ::testing::TestWithParam<IndexKind> {
 protected:
  void SetUp() override {
    BuildOptions options;
    options.threads = 2;
    options.progress = false;
    options.index = GetParam();
    options.vocabulary.depth = 3;
    BuildDatabase(ListImageFolder(kImages, 1, 30), options, Dir(), "rtabmap 1..30");
  }
  std::string Dir() const { return tmp_.Path("db"); }
  static Frame FrameOf(int id) {
    Frame f;
    f.id = id;
    f.image_path = RtabmapImage(id);
    f.timestamp = id;
    return f;
  }
  // The features of images 41..44, the queries of the concurrent tests.
  static std::vector<FeatureSet> QueryFeatures(const PlaceDatabase& db) {
    std::vector<FeatureSet> queries;
    for (int id = 41; id <= 44; ++id) queries.push_back(db.Extract(cv::imread(RtabmapImage(id))));
    return queries;
  }
  static QueryOptions Options() {
    QueryOptions o;
    if (GetParam() == IndexKind::kBow) {
      o.retrieval.method = RetrievalMethod::kBow;
      o.retrieval.bow_candidates = 8;
    }
    return o;
  }

  testing_util::TempDir tmp_;
};

// Added keyframes answer at once; removed ones never again; a saved and
// reopened database answers every query as the changed session did.
TEST_P(OnlineTest, AddRemoveSaveReopen) {
  PlaceDatabase db = PlaceDatabase::Open(Dir());
  const QueryOptions options = Options();
  for (int id = 31; id <= 45; ++id) db.Add(FrameOf(id), cv::imread(RtabmapImage(id)));
  EXPECT_EQ(db.size(), 45u);
  EXPECT_EQ(db.num_pending_changes(), 15u);
  const QueryResult self = db.Query(cv::imread(RtabmapImage(40)), options);
  ASSERT_NE(self.best(), nullptr);
  EXPECT_EQ(self.best()->keyframe_id, 40);
  EXPECT_TRUE(fs::exists(self.best()->stored_image)) << self.best()->stored_image;
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { db.Add(FrameOf(40), cv::imread(RtabmapImage(40))); }, "taken"));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.Add(FrameOf(46), cv::Mat()); }, "empty"));

  EXPECT_TRUE(db.Remove(40));
  EXPECT_FALSE(db.Remove(40));
  EXPECT_FALSE(db.Remove(999));
  EXPECT_TRUE(db.Remove(3));
  EXPECT_EQ(db.size(), 43u);
  EXPECT_FALSE(db.FindKeyframe(40));
  const QueryResult gone = db.Query(cv::imread(RtabmapImage(40)), options);
  for (const RankedKeyframe& k : gone.ranked) EXPECT_NE(k.keyframe_id, 40);

  std::vector<QueryResult> before;
  for (int id = 46; id <= 84; ++id)
    before.push_back(db.Query(cv::imread(RtabmapImage(id)), options));
  db.Save();
  EXPECT_EQ(db.num_pending_changes(), 0u);
  EXPECT_FALSE(fs::exists(fs::path(Dir()) / "images" / "000040.png"));
  const PlaceDatabase reopened = PlaceDatabase::Open(Dir());
  EXPECT_EQ(reopened.size(), 43u);
  EXPECT_FALSE(reopened.FindKeyframe(3));
  ASSERT_TRUE(reopened.FindKeyframe(45));
  for (int id = 46; id <= 84; ++id) {
    const cv::Mat image = cv::imread(RtabmapImage(id));
    EXPECT_EQ(reopened.Query(image, options).ranked, before[id - 46].ranked) << "query " << id;
    EXPECT_EQ(db.Query(image, options).ranked, before[id - 46].ranked) << "query " << id;
  }
  // Only the new generation's files are left.
  int bow_files = 0, keyframe_files = 0;
  for (const auto& e : fs::directory_iterator(Dir())) {
    const std::string name = e.path().filename().string();
    bow_files += IsBowIndexFileName(name);
    keyframe_files += Database::IsKeyframesFileName(name);
  }
  EXPECT_EQ(bow_files, GetParam() == IndexKind::kBow ? 1 : 0);
  EXPECT_EQ(keyframe_files, 1);
}

// The whole-image channel follows the keyframes: Add computes each row from
// the whole frame, a keyframe added from features must bring its row, and
// rows stay aligned with their keyframes through Remove, Save (Compacted)
// and reopening.
TEST_P(OnlineTest, WholeImageRowsFollowAddRemoveSave) {
  const auto rows_match = [](const PlaceDatabase& session, size_t expected) {
    const StorageView view(session);
    const Database& d = view.database();
    ASSERT_EQ(d.whole_image_dims(), 512);  // the default HOG channel
    ASSERT_EQ(d.size(), expected);
    for (size_t i = 0; i < d.size(); ++i) {
      const cv::Mat row = session.Extract(cv::imread(d.keyframe(i).source)).whole_image;
      ASSERT_EQ(row.cols, 512);
      EXPECT_EQ(std::memcmp(d.WholeImage(i), row.data, 512), 0) << "keyframe " << d.keyframe(i).id;
    }
  };
  PlaceDatabase db = PlaceDatabase::Open(Dir());
  EXPECT_EQ(db.whole_image_dims(), 512);
  for (int id = 31; id <= 34; ++id) db.Add(FrameOf(id), cv::imread(RtabmapImage(id)));
  rows_match(db, 34);
  // From features: without a row (or with one of another size) refused.
  const cv::Mat image = cv::imread(RtabmapImage(35));
  FeatureSet features = db.Extract(image);
  ASSERT_EQ(features.whole_image.cols, 512);
  Keyframe k;
  k.id = 35;
  k.source = RtabmapImage(35);
  k.original_size = k.stored_size = image.size();
  k.crop = cv::Rect(0, 0, image.cols, image.rows);
  FeatureSet without = features;
  without.whole_image.release();
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.Add(k, without); }, "whole-image"));
  without.whole_image = features.whole_image.colRange(0, 400).clone();
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { db.Add(k, without); }, "whole-image"));
  db.Add(k, features);
  EXPECT_EQ(cv::norm(db.KeyframeFeatures(35).whole_image, features.whole_image, cv::NORM_L1), 0.0);
  EXPECT_TRUE(db.Remove(3));
  EXPECT_TRUE(db.Remove(32));
  rows_match(db, 35);  // removed keyframes are only masked until saved
  db.Save();
  rows_match(db, 33);
  rows_match(PlaceDatabase::Open(Dir()), 33);
}

// Two threads query without pause while a writer adds and removes
// keyframes: every answer is a consistent view (run under ThreadSanitizer in
// make check), and afterwards every change is visible.
TEST_P(OnlineTest, QueriesRunWhileTheMapGrows) {
  OpenOptions open;
  open.threads = 1;
  PlaceDatabase db = PlaceDatabase::Open(Dir(), open);
  const QueryOptions options = Options();
  const std::vector<FeatureSet> queries = QueryFeatures(db);
  std::vector<cv::Mat> images;
  for (int id = 31; id <= 40; ++id) images.push_back(cv::imread(RtabmapImage(id)));
  std::atomic<bool> done{false};
  std::atomic<int> answered{0};
  auto reader = [&] {
    size_t i = 0;
    while (!done.load()) {
      const QueryResult r = db.Query(queries[i++ % queries.size()], options);
      for (const RankedKeyframe& k : r.ranked) {
        EXPECT_GE(k.keyframe_id, 1);
        EXPECT_LE(k.keyframe_id, 40);
        EXPECT_NE(k.keyframe_id, 1);  // removed before the readers started
      }
      EXPECT_LE(r.num_keyframes, 40u);
      ++answered;
    }
  };
  ASSERT_TRUE(db.Remove(1));
  std::thread a(reader), b(reader);
  for (int id = 31; id <= 40; ++id) {
    db.Add(FrameOf(id), images[id - 31]);
    if (id == 35) db.Remove(2);
  }
  while (answered.load() < 4) std::this_thread::yield();
  done = true;
  a.join();
  b.join();
  EXPECT_EQ(db.size(), 38u);
  const QueryResult r = db.Query(db.Extract(images.back()), options);
  ASSERT_NE(r.best(), nullptr);
  EXPECT_EQ(r.best()->keyframe_id, 40);
}

// Safe by construction: two writers (adds and removes), a Save loop and four
// query threads at once, bounded by counts (ThreadSanitizer in make check).
// Every answer names only keyframes that exist; afterwards the session, a
// last Save and a reopened database agree keyframe for keyframe and answer
// for answer.
TEST_P(OnlineTest, TwoWritersSaveAndFourReadersAtOnce) {
  OpenOptions open;
  open.threads = 1;
  PlaceDatabase db = PlaceDatabase::Open(Dir(), open);
  const QueryOptions options = Options();
  const std::vector<FeatureSet> queries = QueryFeatures(db);
  std::vector<cv::Mat> images(13);
  for (int id = 31; id <= 43; ++id) images[id - 31] = cv::imread(RtabmapImage(id));
  std::atomic<int> writers_left{3};
  std::atomic<int> answered{0};
  std::atomic<int> saves{0};
  auto reader = [&](int r) {
    // At least 3 queries each, and on until every writer is done.
    for (int i = 0; i < 3 || writers_left.load() > 0; ++i) {
      const QueryResult q = db.Query(queries[(r + i) % queries.size()], options);
      for (const RankedKeyframe& k : q.ranked) {
        EXPECT_GE(k.keyframe_id, 1);
        EXPECT_LE(k.keyframe_id, 43);
      }
      EXPECT_LE(q.num_keyframes, 43u);
      ++answered;
      // Snapshots stay valid whatever the writers do next.
      const std::optional<Keyframe> k = db.FindKeyframe(5 + r);
      if (k) {
        EXPECT_EQ(k->id, 5 + r);
      }
      EXPECT_FALSE(StorageView(db).database().info().empty());
    }
  };
  // Writer 1 adds 31..37 and removes 1..4; writer 2 adds 38..43 and removes
  // 10..13 (and tries ids writer 1 owns: one of each pair wins).
  auto writer = [&](int first, int last, int remove_first) {
    for (int id = first; id <= last; ++id) {
      db.Add(FrameOf(id), images[id - 31]);
      db.Remove(remove_first + (id - first) % 4);
    }
    --writers_left;
  };
  auto saver = [&] {
    for (int i = 0; i < 3; ++i) {
      db.Save();
      ++saves;
    }
    --writers_left;
  };
  std::vector<std::thread> threads;
  for (int r = 0; r < 4; ++r) threads.emplace_back(reader, r);
  threads.emplace_back(writer, 31, 37, 1);
  threads.emplace_back(writer, 38, 43, 10);
  threads.emplace_back(saver);
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(saves.load(), 3);
  EXPECT_GE(answered.load(), 12);
  // 30 + 13 added - 8 removed.
  EXPECT_EQ(db.size(), 35u);
  for (int id : {1, 2, 3, 4, 10, 11, 12, 13}) EXPECT_FALSE(db.FindKeyframe(id)) << id;
  for (int id = 31; id <= 43; ++id) EXPECT_TRUE(db.FindKeyframe(id)) << id;
  std::vector<QueryResult> before;
  for (const FeatureSet& q : queries) before.push_back(db.Query(q, options));
  db.Save();
  EXPECT_EQ(db.num_pending_changes(), 0u);
  const PlaceDatabase reopened = PlaceDatabase::Open(Dir(), open);
  EXPECT_EQ(reopened.keyframe_ids(), db.keyframe_ids());
  for (size_t i = 0; i < queries.size(); ++i) {
    EXPECT_EQ(reopened.Query(queries[i], options).ranked, before[i].ranked) << "query " << i;
    EXPECT_EQ(db.Query(queries[i], options).ranked, before[i].ranked) << "query " << i;
  }
  // Every kept keyframe's PNG is there, and no other file is in images/.
  std::set<std::string> expected, found;
  for (const int32_t id : reopened.keyframe_ids()) {
    expected.insert(fs::path(reopened.FindKeyframe(id)->image_file).filename().string());
  }
  for (const auto& e : fs::directory_iterator(Dir() + "/images"))
    found.insert(e.path().filename().string());
  EXPECT_EQ(found, expected);
}

// Two adds of one id at once: one wins, the other is told the id is taken,
// and the stored PNG is the winner's, whole.
TEST_P(OnlineTest, TwoAddsOfOneIdOneWins) {
  PlaceDatabase db = PlaceDatabase::Open(Dir());
  const cv::Mat a = cv::imread(RtabmapImage(31)), b = cv::imread(RtabmapImage(60));
  std::atomic<int> taken{0};
  auto add = [&](const cv::Mat& image) {
    try {
      db.Add(FrameOf(31), image);
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find("is taken"), std::string::npos) << e.what();
      ++taken;
    }
  };
  std::thread t1(add, a), t2(add, b);
  t1.join();
  t2.join();
  EXPECT_EQ(taken.load(), 1);
  db.Save();
  const PlaceDatabase reopened = PlaceDatabase::Open(Dir());
  const std::optional<Keyframe> k = reopened.FindKeyframe(31);
  ASSERT_TRUE(k);
  const cv::Mat stored = cv::imread(reopened.StoredImagePath(*k));
  ASSERT_FALSE(stored.empty());
  EXPECT_EQ(stored.size(), a.size());
  for (const auto& e : fs::directory_iterator(Dir() + "/images"))
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
}

// An add that fails after its image was encoded leaves no file behind.
TEST_P(OnlineTest, AFailedAddLeavesNothingBehind) {
  PlaceDatabase db = PlaceDatabase::Open(Dir());
  const size_t files =
      std::distance(fs::directory_iterator(Dir() + "/images"), fs::directory_iterator());
  Frame bad = FrameOf(31);
  bad.timestamp = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(
      ThrowsWith<InvalidArgument>([&] { db.Add(bad, cv::imread(RtabmapImage(31))); }, "timestamp"));
  EXPECT_EQ(std::distance(fs::directory_iterator(Dir() + "/images"), fs::directory_iterator()),
            static_cast<std::ptrdiff_t>(files));
  EXPECT_FALSE(fs::exists(Dir() + "/images/000031.png"));
  EXPECT_EQ(db.size(), 30u);
  // A session dropped unsaved takes its images with it.
  {
    PlaceDatabase other = PlaceDatabase::Open(Dir());
    (void)other;
  }
  db.Add(FrameOf(32), cv::imread(RtabmapImage(32)));
  EXPECT_TRUE(fs::exists(Dir() + "/images/000032.png"));
  db = PlaceDatabase::Open(Dir());  // the unsaved session ends
  EXPECT_FALSE(fs::exists(Dir() + "/images/000032.png"));
  EXPECT_FALSE(db.FindKeyframe(32));
}

// One writer per database across sessions and processes; a session whose
// database was rewritten since it opened may not write over it.
TEST_P(OnlineTest, OneWriterAtATimeAndNoLostUpdates) {
  PlaceDatabase first = PlaceDatabase::Open(Dir());
  PlaceDatabase second = PlaceDatabase::Open(Dir());
  first.Add(FrameOf(31), cv::imread(RtabmapImage(31)));
  EXPECT_TRUE(ThrowsWith<IoError>([&] { second.Remove(1); }, "another process"));
  first.Save();
  // first has saved (and let go): second's view is now stale.
  EXPECT_TRUE(ThrowsWith<IoError>([&] { second.Remove(1); }, "rewritten on disk"));
  EXPECT_TRUE(second.FindKeyframe(1));
  PlaceDatabase third = PlaceDatabase::Open(Dir());
  EXPECT_TRUE(third.Remove(1));
  third.Save();
  EXPECT_EQ(PlaceDatabase::Open(Dir()).size(), 30u);
}

// The deadline starts before a query waits for the lock: with a writer
// waiting for a reader that does not let go, a query under a deadline gives
// up when its deadline passes (instead of waiting for the reader), and says
// so: nothing examined, deadline_reached.
TEST_P(OnlineTest, DeadlineCountsTheWaitForAWriter) {
  PlaceDatabase db = PlaceDatabase::Open(Dir());
  const FeatureSet query = db.Extract(cv::imread(RtabmapImage(41)));
  QueryOptions options = Options();
  options.deadline_ms = 20;
  // Another thread holds a View until told; while it does, it also reads
  // again (a nested read behind the waiting writer must not deadlock).
  std::atomic<int> stage{0};  // 1: holding, 2: read again, 3: nested read done, 4: release
  std::thread holder([&] {
    const StorageView view(db);
    stage = 1;
    while (stage.load() < 2) std::this_thread::yield();
    EXPECT_TRUE(db.FindKeyframe(5));
    EXPECT_EQ(StorageView(db).database().info()["counts"]["keyframes"], 30);
    stage = 3;
    while (stage.load() < 4) std::this_thread::yield();
  });
  while (stage.load() < 1) std::this_thread::yield();
  std::thread writer([&] { db.Remove(2); });  // waits for the view
  // Once the writer waits, every query under a deadline gives up; before,
  // they answer. Bounded: the writer gets there.
  QueryResult r;
  for (int i = 0; i < 100000; ++i) {
    r = db.Query(query, options);
    if (r.num_examined == 0) break;
    std::this_thread::yield();
  }
  EXPECT_TRUE(r.deadline_reached);
  EXPECT_EQ(r.num_examined, 0u);
  EXPECT_TRUE(r.ranked.empty());
  EXPECT_FALSE(r.matched);
  stage = 2;
  while (stage.load() < 3) std::this_thread::yield();
  stage = 4;
  holder.join();
  writer.join();
  EXPECT_FALSE(db.FindKeyframe(2));
  EXPECT_GT(db.Query(query, options).num_examined, 0u);
}

// Saving a subset over the whole database is refused (it would replace it).
TEST_P(OnlineTest, SavingASubsetOverTheDatabaseIsRefused) {
  const Database part = Database::Load(Dir(), KeyframeSubset::Partition(0, 2));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { part.Save(Dir()); }, "subset would replace"));
  EXPECT_EQ(Database::Load(Dir()).size(), 30u);
  fs::create_directories(tmp_.Path("part"));
  part.Save(tmp_.Path("part"));
  EXPECT_EQ(Database::Load(tmp_.Path("part")).size(), 15u);
}

// What killed writers leave (temporary files of gone processes, keyframe and
// index files no manifest names, PNGs of placedb's naming no keyframe names)
// is left by a read and swept by the next writer's first change and its
// save; a live process's temporary file, a user's file and symlinks are left
// alone.
TEST_P(OnlineTest, DebrisOfKilledWritersIsSweptByTheNextWriter) {
  const std::string dir = Dir();
  auto touch = [](const std::string& path) { std::ofstream(path) << "debris"; };
  const std::string gone = "99999999";  // above any pid_max: a gone process
  const std::vector<std::string> debris = {
      dir + "/keyframes.bin.tmp." + gone + ".1",
      dir + "/keyframes.writing.bin.tmp." + gone,
      dir + "/manifest.json.tmp." + gone + ".7",
      dir + "/keyframes.writing.bin",
      dir + "/keyframes.0123456789abcdef.bin",
      dir + "/bow.0123456789abcdef.bin",
      dir + "/images/000777.png",
      dir + "/images/000031.png.tmp." + gone + ".3",
  };
  for (const std::string& path : debris) touch(path);
  const std::string live = dir + "/manifest.json.tmp." + std::to_string(::getpid()) + ".99";
  touch(live);
  const std::string outside = tmp_.Path("outside.png");
  touch(outside);
  fs::create_symlink(outside, dir + "/images/000888.png");
  const std::string users = dir + "/images/holiday.png";
  touch(users);
  PlaceDatabase db = PlaceDatabase::Open(Dir());
  db.Query(cv::imread(RtabmapImage(2)));
  for (const std::string& path : debris) EXPECT_TRUE(fs::exists(path)) << "a read removed " << path;
  db.Remove(3);  // the first change: the writer sweeps
  for (const std::string& path : debris) EXPECT_FALSE(fs::exists(path)) << path;
  EXPECT_TRUE(fs::exists(live));
  EXPECT_TRUE(fs::exists(outside));
  EXPECT_TRUE(fs::exists(users));
  EXPECT_TRUE(fs::is_symlink(dir + "/images/000888.png"));
  EXPECT_EQ(db.size(), 29u);
  EXPECT_TRUE(fs::exists(dir + "/images/000001.png"));
  EXPECT_TRUE(fs::exists(dir + "/images/000003.png"));  // not saved yet
  fs::remove(live);
  fs::remove(dir + "/images/000888.png");
  // The same at the Save.
  for (const std::string& path : debris) touch(path);
  db.Save();
  for (const std::string& path : debris) EXPECT_FALSE(fs::exists(path)) << path;
  EXPECT_FALSE(fs::exists(dir + "/images/000003.png"));
  EXPECT_TRUE(fs::exists(users));
}

// Real kills: a writer process (add, save, remove, save, ...) killed with
// SIGKILL at moments spread over its work; after each, a read changes
// nothing, and the next writer leaves only what the manifest names: its
// keyframe file, its index files, the PNGs of its keyframes, and no
// temporary file.
TEST_P(OnlineTest, NoDebrisSurvivesTheNextOpenAfterKills) {
  if (testing_util::kThreadSanitizer) GTEST_SKIP() << "forks: not under ThreadSanitizer";
  const std::string dir = Dir();
  std::vector<cv::Mat> images;
  for (int id = 31; id <= 36; ++id) images.push_back(cv::imread(RtabmapImage(id)));
  // OpenCV's worker threads do not survive fork: sequential meanwhile.
  struct SequentialOpenCv {
    const int saved = cv::getNumThreads();
    SequentialOpenCv() { cv::setNumThreads(0); }
    ~SequentialOpenCv() { cv::setNumThreads(saved); }
  } sequential;
  for (int round = 0; round < 6; ++round) {
    SCOPED_TRACE("round " + std::to_string(round));
    int ready[2];
    ASSERT_EQ(::pipe(ready), 0);
    const pid_t pid = ::fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
      ::close(ready[0]);
      int code = 0;
      try {
        PlaceDatabase db = PlaceDatabase::Open(dir);
        bool told = false;
        for (int step = 0;; ++step) {  // until killed
          const int id = 31 + step % 6;
          if (db.FindKeyframe(id)) {
            db.Remove(id);
          } else {
            db.Add(FrameOf(id), images[id - 31]);
          }
          if (!told) {
            // The first change is made: the parent's clock starts now.
            told = ::write(ready[1], "x", 1) == 1;
          }
          if (step % 2 == 1) db.Save();
        }
      } catch (...) {
        code = 3;
      }
      ::_exit(code);
    }
    ::close(ready[1]);
    char byte = 0;
    const bool started = ::read(ready[0], &byte, 1) == 1;
    ::close(ready[0]);
    // Kill moments spread over adds, saves and removes.
    std::this_thread::sleep_for(std::chrono::milliseconds(37 * round * round));
    ::kill(pid, SIGKILL);
    int status = 0;
    ::waitpid(pid, &status, 0);
    ASSERT_TRUE(started) << "the writer failed before its first change";
    ASSERT_TRUE(WIFSIGNALED(status)) << "the writer ended by itself, code " << WEXITSTATUS(status);

    auto listing = [&] {
      std::set<std::string> names;
      for (const auto& e : fs::recursive_directory_iterator(dir))
        names.insert(e.path().lexically_relative(dir).string());
      return names;
    };
    const std::set<std::string> before = listing();
    PlaceDatabase::Open(dir).Query(images[0]);
    EXPECT_EQ(listing(), before) << "a read changed the folder";
    {
      PlaceDatabase writer = PlaceDatabase::Open(dir);
      const int32_t id = writer.keyframe_ids().front();
      writer.Remove(id);
      writer.Save();
    }
    const PlaceDatabase db = PlaceDatabase::Open(dir);
    const nlohmann::json manifest = StorageView(db).database().info();
    std::set<std::string> named = {"manifest.json", "images",
                                   manifest["files"]["keyframes"].get<std::string>()};
    if (manifest.contains("index")) {
      named.insert(manifest["index"]["vocabulary"].get<std::string>());
      named.insert(manifest["index"]["bow"].get<std::string>());
    }
    if (manifest.contains("whole_image_model"))
      named.insert(manifest["whole_image_model"].get<std::string>());
    std::set<std::string> top, pngs, expected_pngs;
    for (const auto& e : fs::directory_iterator(dir)) top.insert(e.path().filename().string());
    EXPECT_EQ(top, named);
    for (const int32_t id : db.keyframe_ids()) {
      expected_pngs.insert(fs::path(db.FindKeyframe(id)->image_file).filename().string());
    }
    for (const auto& e : fs::directory_iterator(dir + "/images"))
      pngs.insert(e.path().filename().string());
    EXPECT_EQ(pngs, expected_pngs);
  }
}

TEST_P(OnlineTest, SubsetSessionsCannotChange) {
  OpenOptions open;
  open.subset = KeyframeSubset::Partition(0, 2, PartitionScheme::kContiguous);
  PlaceDatabase part = PlaceDatabase::Open(Dir(), open);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { part.Remove(1); }, "whole database"));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { part.Save(); }, "whole database"));
}

INSTANTIATE_TEST_SUITE_P(Index, OnlineTest, ::testing::Values(IndexKind::kNone, IndexKind::kBow),
                         [](const auto& info) { return std::string(IndexKindName(info.param)); });

}  // namespace
}  // namespace placedb
