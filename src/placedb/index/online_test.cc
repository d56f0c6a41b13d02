// Online mapping: keyframes added and removed while queries run, saved and
// reopened.
#include <gtest/gtest.h>

#include <atomic>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <thread>

#include "placedb/dataset/image_folder.h"
#include "placedb/index/place_database.h"
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
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>(
      [&] { db.Add(FrameOf(40), cv::imread(RtabmapImage(40))); }, "taken"));
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>([&] { db.Add(FrameOf(46), cv::Mat()); }, "empty"));

  EXPECT_TRUE(db.Remove(40));
  EXPECT_FALSE(db.Remove(40));
  EXPECT_FALSE(db.Remove(999));
  EXPECT_TRUE(db.Remove(3));
  EXPECT_EQ(db.size(), 43u);
  EXPECT_EQ(db.FindKeyframe(40), nullptr);
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
  EXPECT_EQ(reopened.FindKeyframe(3), nullptr);
  ASSERT_NE(reopened.FindKeyframe(45), nullptr);
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

// Two threads query without pause while a writer adds and removes
// keyframes: every answer is a consistent view (run under ThreadSanitizer in
// make test), and afterwards every change is visible.
TEST_P(OnlineTest, QueriesRunWhileTheMapGrows) {
  OpenOptions open;
  open.threads = 1;
  PlaceDatabase db = PlaceDatabase::Open(Dir(), open);
  const QueryOptions options = Options();
  std::vector<FeatureSet> queries;
  for (int id = 41; id <= 44; ++id) queries.push_back(db.Extract(cv::imread(RtabmapImage(id))));
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

TEST_P(OnlineTest, SubsetSessionsCannotChange) {
  OpenOptions open;
  open.subset = KeyframeSubset::Partition(0, 2, PartitionScheme::kContiguous);
  PlaceDatabase part = PlaceDatabase::Open(Dir(), open);
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>([&] { part.Remove(1); }, "whole database"));
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>([&] { part.Save(); }, "whole database"));
}

INSTANTIATE_TEST_SUITE_P(Index, OnlineTest, ::testing::Values(IndexKind::kNone, IndexKind::kBow),
                         [](const auto& info) { return std::string(IndexKindName(info.param)); });

}  // namespace
}  // namespace placedb
