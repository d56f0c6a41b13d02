#include "placedb/dataset/image_folder.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>

#include "placedb/util/testing.h"

namespace placedb {
namespace {

namespace fs = std::filesystem;
using testing_util::TempDir;
using testing_util::ThrowsWith;

const std::string kData = PLACEDB_DATA_DIR;

std::string FileName(const Frame& frame) { return fs::path(frame.image_path).filename().string(); }

TEST(ImageFolderTest, RtabmapLoopHas84SortedImages) {
  const std::string dir = kData + "/rtabmap_loop/images";
  const std::vector<Frame> frames = ListImageFolder(dir);
  ASSERT_EQ(frames.size(), 84u);
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].id, static_cast<int>(i + 1));
    char name[16];
    std::snprintf(name, sizeof(name), "%03d.jpg", static_cast<int>(i + 1));
    EXPECT_EQ(FileName(frames[i]), name);
    EXPECT_EQ(frames[i].timestamp, -1.0);
    EXPECT_FALSE(frames[i].pose.has_value());
  }
  const cv::Mat image = cv::imread(frames[0].image_path);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 512);
  EXPECT_EQ(image.rows, 384);
}

TEST(ImageFolderTest, RangeKeepsIds) {
  const std::string dir = kData + "/rtabmap_loop/images";
  const std::vector<Frame> queries = ListImageFolder(dir, 41, 84);
  ASSERT_EQ(queries.size(), 44u);
  for (size_t i = 0; i < queries.size(); ++i) EXPECT_EQ(queries[i].id, static_cast<int>(41 + i));
  EXPECT_EQ(FileName(queries.front()), "041.jpg");
  EXPECT_EQ(FileName(queries.back()), "084.jpg");

  const std::vector<Frame> database = ListImageFolder(dir, 1, 40);
  ASSERT_EQ(database.size(), 40u);
  EXPECT_EQ(database.back().id, 40);
  EXPECT_EQ(FileName(database.back()), "040.jpg");

  EXPECT_EQ(ListImageFolder(dir, 41).size(), 44u);  // last = 0: to the end
  const std::vector<Frame> one = ListImageFolder(dir, 84, 84);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0].id, 84);
  const std::vector<Frame> clamped = ListImageFolder(dir, 80, 100);  // last clamped, warning
  ASSERT_EQ(clamped.size(), 5u);
  EXPECT_EQ(clamped.back().id, 84);
}

TEST(ImageFolderTest, DeskLoopHasTenPngs) {
  const std::vector<Frame> frames = ListImageFolder(kData + "/tum_fr2_desk_loop/rgb");
  ASSERT_EQ(frames.size(), 10u);
  EXPECT_EQ(FileName(frames[0]), "01.png");
  EXPECT_EQ(FileName(frames[9]), "10.png");
  EXPECT_EQ(frames[9].id, 10);
  const cv::Mat image = cv::imread(frames[9].image_path);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 640);
  EXPECT_EQ(image.rows, 480);
}

TEST(ImageFolderTest, FiltersExtensionsCaseInsensitivelyAndSortsByName) {
  TempDir tmp;
  for (const char* name : {"b.PNG", "a.jpg", "e.JpEg", "f.tiff", "g.webp", "notes.txt",
                           ".hidden.jpg", "noext", "sub/d.jpg"}) {
    tmp.Write(name, "x");
  }
  fs::create_directories(tmp.Path("dir.png"));  // a directory with an image extension
  const std::vector<Frame> frames = ListImageFolder(tmp.Path());
  ASSERT_EQ(frames.size(), 5u);
  EXPECT_EQ(FileName(frames[0]), "a.jpg");
  EXPECT_EQ(FileName(frames[1]), "b.PNG");
  EXPECT_EQ(FileName(frames[2]), "e.JpEg");
  EXPECT_EQ(FileName(frames[3]), "f.tiff");
  EXPECT_EQ(FileName(frames[4]), "g.webp");
  EXPECT_EQ(frames[0].image_path, tmp.Path("a.jpg"));
}

TEST(ImageFolderTest, FolderErrorsNameTheDir) {
  TempDir tmp;
  const std::string missing = tmp.Path("missing");
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>([&] { ListImageFolder(missing); }, {missing}));

  tmp.Write("empty/readme.txt", "no images here");
  const std::string empty = tmp.Path("empty");
  EXPECT_TRUE(
      ThrowsWith<std::invalid_argument>([&] { ListImageFolder(empty); }, {empty, "no images"}));

  const std::string dir = kData + "/tum_fr2_desk_loop/rgb";
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>([&] { ListImageFolder(dir, 5, 3); },
                                                {dir, "first (5) > last (3)"}));
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>([&] { ListImageFolder(dir, 11); },
                                                {dir, "beyond the 10 images"}));
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>([&] { ListImageFolder(dir, 0); }, {dir, "first"}));
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>([&] { ListImageFolder(dir, 1, -1); }, {dir}));
}

TEST(ImageFolderTest, ImageListWithRelativePathsAndComments) {
  TempDir tmp;
  tmp.Write("img/x.png", "x");
  tmp.Write("lists/y.jpg", "y");
  const std::string desk03 = kData + "/tum_fr2_desk_loop/rgb/03.png";
  const std::string list = tmp.Write("lists/list.txt",
                                     "# images of the test\n"
                                     "\n"
                                     "../img/x.png\r\n"
                                     "   # an indented comment\n"
                                     "  y.jpg  \n" +
                                         desk03 + "\n");
  const std::vector<Frame> frames = ReadImageList(list);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].id, 1);
  EXPECT_EQ(frames[1].id, 2);
  EXPECT_EQ(frames[2].id, 3);
  EXPECT_TRUE(fs::equivalent(frames[0].image_path, tmp.Path("img/x.png")));
  EXPECT_EQ(frames[1].image_path, tmp.Path("lists/y.jpg"));
  EXPECT_EQ(frames[2].image_path, desk03);  // absolute entries are kept as they are
  EXPECT_FALSE(cv::imread(frames[2].image_path).empty());

  const std::vector<Frame> tail = ReadImageList(list, 2);
  ASSERT_EQ(tail.size(), 2u);
  EXPECT_EQ(tail[0].id, 2);
  EXPECT_EQ(tail[0].image_path, tmp.Path("lists/y.jpg"));
}

TEST(ImageFolderTest, ImageListErrors) {
  TempDir tmp;
  tmp.Write("a.png", "x");
  const std::string list = tmp.Write("list.txt", "# header\na.png\nmissing.png\n");
  // A missing image is kept (ids are list positions); the build skips it.
  const std::vector<Frame> frames = ReadImageList(list);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[1].id, 2);
  EXPECT_NE(frames[1].image_path.find("missing.png"), std::string::npos);
  const std::string only_comments = tmp.Write("comments.txt", "# nothing\n\n");
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>([&] { ReadImageList(only_comments); },
                                                {only_comments, "no images"}));
  const std::string good = tmp.Write("good.txt", "a.png\n");
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>([&] { ReadImageList(good, 2); }, {good}));
  EXPECT_TRUE(ThrowsWith<std::invalid_argument>([&] { ReadImageList(tmp.Path("nope.txt")); },
                                                {"nope.txt"}));
}

TEST(ImageFolderTest, ReadImagesDispatches) {
  EXPECT_EQ(ReadImages(kData + "/tum_fr2_desk_loop/rgb", 2, 4).size(), 3u);
  TempDir tmp;
  const std::string list = tmp.Write("list.txt", kData + "/rtabmap_loop/images/084.jpg\n");
  const std::vector<Frame> frames = ReadImages(list);
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(FileName(frames[0]), "084.jpg");
  EXPECT_TRUE(
      ThrowsWith<std::invalid_argument>([&] { ReadImages(tmp.Path("none")); }, {tmp.Path("none")}));
}

}  // namespace
}  // namespace placedb
