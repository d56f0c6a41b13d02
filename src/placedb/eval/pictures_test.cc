#include "placedb/eval/pictures.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <opencv2/imgcodecs.hpp>

#include "placedb/dataset/image_folder.h"
#include "placedb/builder/builder.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
using testing_util::RtabmapImage;
using testing_util::TempDir;
using testing_util::ThrowsWith;

// Pixels of `image` close to `color`.
int CountColor(const cv::Mat& image, const cv::Scalar& color) {
  cv::Mat mask;
  cv::inRange(image, color - cv::Scalar(8, 8, 8), color + cv::Scalar(8, 8, 8), mask);
  return cv::countNonZero(mask);
}

TEST(PicturesTest, DrawsAQueryAgainstItsKeyframe) {
  TempDir tmp;
  BuildOptions b;
  b.progress = false;
  b.threads = 1;
  BuildDatabase(ReadImages(PLACEDB_DATA_DIR "/rtabmap_loop/images", 1, 6), b, tmp.Path("db"), "t");
  const PlaceDatabase db = PlaceDatabase::Open(tmp.Path("db"));
  const cv::Mat query = cv::imread(RtabmapImage(3));
  MatchDetail d;
  const cv::Mat picture = DrawQueryMatch(db, query, db.Extract(query), 3, QueryOptions(), "q", &d);
  // The image against itself: every match verified, every line green.
  EXPECT_GT(d.matches.size(), 100u);
  ASSERT_TRUE(d.verified);
  EXPECT_EQ(d.inliers.size(), d.matches.size());
  EXPECT_GT(d.num_inliers, static_cast<int>(d.matches.size()) * 9 / 10);
  EXPECT_EQ(picture.rows, 360 + 2 * 24);  // two caption lines
  EXPECT_GT(picture.cols, 2 * 360);
  EXPECT_GT(CountColor(picture, kInlierColor), 1000);
  // Explain agrees with the query's own numbers.
  const QueryResult r = db.Query(query);
  ASSERT_TRUE(r.best());
  EXPECT_EQ(r.best()->keyframe_id, 3);
  EXPECT_EQ(r.best()->num_matches, static_cast<int>(d.matches.size()));
  EXPECT_EQ(r.best()->num_inliers, d.num_inliers);
  // Lost matches are drawn red.
  MatchPicture p;
  p.query = query;
  p.keyframe = query;
  p.detail = &d;
  p.lost.assign(d.matches.size(), 1);
  p.lost[0] = 0;
  d.verified = false;
  EXPECT_GT(CountColor(DrawMatchPicture(p), kLostColor), 1000);
  p.lost.resize(3);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { DrawMatchPicture(p); }, "lost list"));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { DrawQueryMatch(db, query, db.Extract(query), 99, QueryOptions(), ""); },
      "no keyframe 99"));
  p.lost.clear();
  p.query = cv::Mat();
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { DrawMatchPicture(p); }, "empty"));
}

TEST(PicturesTest, DrawsTheCropAndRows) {
  const cv::Mat image = cv::imread(RtabmapImage(10));
  const CropOptions options;
  const CropResult crop = SelectFeatureRichCrop(image, options);
  const cv::Mat picture = DrawCropIllustration(image, crop, options, {1, 4, 16});
  EXPECT_EQ(picture.rows, image.rows + 24);
  EXPECT_GT(picture.cols, image.cols + 3 * 150);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { DrawCropIllustration(image, crop, options, {2}); },
                                          "area divisor"));
  const cv::Mat row = DrawImageRow({image, cv::Mat(), image}, {"a", "b", "c"}, 100);
  EXPECT_EQ(row.rows, 124);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { DrawImageRow({}, {}, 100); }, "no images"));
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { DrawImageRow({image}, {}, 8); }, "height"));
}

}  // namespace
}  // namespace placedb
