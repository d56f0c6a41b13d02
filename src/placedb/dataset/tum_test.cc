#include "placedb/dataset/tum.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <stdexcept>

#include "placedb/util/testing.h"

namespace placedb {
namespace {

namespace fs = std::filesystem;
using testing_util::TempDir;
using testing_util::ThrowsWith;

const std::string kData = PLACEDB_DATA_DIR;

// One row of the shipped rgb_gt_associated.txt (written independently of the
// reader under test): rgb_ts rgb_file gt_ts tx ty tz qx qy qz qw |dt|.
struct AssociatedRow {
  double rgb_timestamp;
  std::string rgb_file;
  Pose pose;
  double dt;
};

std::vector<AssociatedRow> ReadAssociated(const std::string& path) {
  std::ifstream in(path);
  std::vector<AssociatedRow> rows;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    AssociatedRow row;
    double gt_t, tx, ty, tz, qx, qy, qz, qw;
    fields >> row.rgb_timestamp >> row.rgb_file >> gt_t >> tx >> ty >> tz >> qx >> qy >> qz >> qw >>
        row.dt;
    EXPECT_FALSE(fields.fail()) << line;
    row.pose.translation = Eigen::Vector3d(tx, ty, tz);
    row.pose.rotation = Eigen::Quaterniond(qw, qx, qy, qz).normalized();
    rows.push_back(row);
  }
  return rows;
}

void ExpectPoseEq(const Pose& actual, const Pose& expected) {
  EXPECT_NEAR((actual.translation - expected.translation).norm(), 0.0, 1e-12);
  EXPECT_NEAR((actual.rotation.coeffs() - expected.rotation.coeffs()).norm(), 0.0, 1e-12);
}

TEST(TumTest, Fr3OfficeDefaultLeavesFirstFramePoseless) {
  const std::string dir = kData + "/tum_fr3_office_mini";
  const std::vector<Frame> frames = ReadTumSequence(dir);
  const std::vector<AssociatedRow> expected = ReadAssociated(dir + "/rgb_gt_associated.txt");
  ASSERT_EQ(frames.size(), 4u);
  ASSERT_EQ(expected.size(), 4u);
  for (size_t i = 0; i < frames.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(frames[i].id, static_cast<int>(i + 1));
    EXPECT_DOUBLE_EQ(frames[i].timestamp, expected[i].rgb_timestamp);
    EXPECT_EQ(frames[i].image_path, dir + "/" + expected[i].rgb_file);
    EXPECT_EQ(frames[i].pose.has_value(), expected[i].dt <= 0.02);
    if (frames[i].pose) ExpectPoseEq(*frames[i].pose, expected[i].pose);
  }
  // |dt| of the first frame: GT starts 0.067 s after it.
  EXPECT_NEAR(expected[0].dt, 0.067, 1e-9);
  EXPECT_FALSE(frames[0].pose.has_value());

  // Frame 2, numbers straight from the files.
  EXPECT_NEAR(frames[1].timestamp, 1341847984.106759, 1e-6);
  ASSERT_TRUE(frames[1].pose.has_value());
  const Pose& pose = *frames[1].pose;
  EXPECT_NEAR(pose.translation.x(), 0.0258, 1e-12);
  EXPECT_NEAR(pose.translation.y(), 2.7128, 1e-12);
  EXPECT_NEAR(pose.translation.z(), 1.7191, 1e-12);
  EXPECT_NEAR(pose.rotation.x(), 0.0742, 1e-4);
  EXPECT_NEAR(pose.rotation.y(), 0.8564, 1e-4);
  EXPECT_NEAR(pose.rotation.z(), -0.5058, 1e-4);
  EXPECT_NEAR(pose.rotation.w(), -0.0727, 1e-4);
  EXPECT_NEAR(pose.rotation.norm(), 1.0, 1e-12);

  const cv::Mat image = cv::imread(frames[1].image_path);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 640);
  EXPECT_EQ(image.rows, 480);
}

TEST(TumTest, Fr3OfficeWiderWindowGivesEveryFrameItsPose) {
  const std::string dir = kData + "/tum_fr3_office_mini";
  TumOptions options;
  options.max_time_difference = 0.07;
  const std::vector<Frame> frames = ReadTumSequence(dir, options);
  const std::vector<AssociatedRow> expected = ReadAssociated(dir + "/rgb_gt_associated.txt");
  ASSERT_EQ(frames.size(), 4u);
  for (size_t i = 0; i < frames.size(); ++i) {
    ASSERT_TRUE(frames[i].pose.has_value()) << i;
    ExpectPoseEq(*frames[i].pose, expected[i].pose);
  }
  EXPECT_NEAR(frames[0].pose->translation.x(), -0.6832, 1e-12);
  EXPECT_NEAR(frames[0].pose->translation.y(), 2.6909, 1e-12);
  EXPECT_NEAR(frames[0].pose->translation.z(), 1.7373, 1e-12);

  // A tight window: |dt| of frames 2, 3, 4 is 0.0032, 0.0036, 0.0008 s.
  options.max_time_difference = 0.003;
  const std::vector<Frame> tight = ReadTumSequence(dir, options);
  EXPECT_FALSE(tight[0].pose.has_value());
  EXPECT_FALSE(tight[1].pose.has_value());
  EXPECT_FALSE(tight[2].pose.has_value());
  EXPECT_TRUE(tight[3].pose.has_value());
}

TEST(TumTest, Fr3OfficeTrajectory) {
  const std::vector<TumPoseStamped> poses =
      ReadTumTrajectory(kData + "/tum_fr3_office_mini/groundtruth.txt");
  ASSERT_EQ(poses.size(), 8710u);
  EXPECT_DOUBLE_EQ(poses.front().timestamp, 1341847980.7900);
  EXPECT_NEAR(poses.front().pose.translation.x(), -0.6832, 1e-12);
  EXPECT_NEAR(poses.front().pose.rotation.y(), 0.8617, 1e-4);
  EXPECT_DOUBLE_EQ(poses.back().timestamp, 1341848067.8795);
  for (const TumPoseStamped& p : poses) ASSERT_NEAR(p.pose.rotation.norm(), 1.0, 1e-12);
}

TEST(TumTest, Fr2PioneerAllFivePosed) {
  const std::string dir = kData + "/tum_fr2_pioneer_mini";
  const std::vector<Frame> frames = ReadTumSequence(dir);
  const std::vector<AssociatedRow> expected = ReadAssociated(dir + "/rgb_gt_associated.txt");
  ASSERT_EQ(frames.size(), 5u);
  ASSERT_EQ(expected.size(), 5u);
  for (size_t i = 0; i < frames.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(frames[i].id, static_cast<int>(i + 1));
    EXPECT_EQ(frames[i].image_path, dir + "/" + expected[i].rgb_file);
    EXPECT_LE(expected[i].dt, 0.0049 + 1e-9);
    ASSERT_TRUE(frames[i].pose.has_value());
    ExpectPoseEq(*frames[i].pose, expected[i].pose);
  }
  EXPECT_NEAR(frames[4].pose->translation.x(), -0.0373, 1e-12);
  EXPECT_NEAR(frames[4].pose->translation.y(), -1.8341, 1e-12);
  EXPECT_NEAR(frames[4].pose->translation.z(), 0.5788, 1e-12);
  EXPECT_NEAR(frames[4].pose->rotation.w(), 0.6649, 1e-4);
  // Frames 1 and 2 are 0.13 m apart (SOURCE.txt).
  EXPECT_NEAR(TranslationDistance(*frames[0].pose, *frames[1].pose), 0.1322, 1e-3);
}

// A synthetic TUM folder: images are placeholders (only their existence is checked).
std::string WriteTumFolder(const TempDir& tmp, const std::string& rgb, const std::string* gt) {
  for (const char* name : {"1.png", "2.png", "3.png", "4.png"}) {
    tmp.Write(std::string("seq/rgb/") + name, "x");
  }
  tmp.Write("seq/rgb.txt", rgb);
  if (gt != nullptr) tmp.Write("seq/groundtruth.txt", *gt);
  return tmp.Path("seq");
}

TEST(TumTest, NearestPoseAndTies) {
  TempDir tmp;
  const std::string gt =
      "# timestamp tx ty tz qx qy qz qw\n"
      "2.0 2 0 0 0 0 0 1\n"  // unsorted on purpose
      "1.0 1 0 0 0 0 0 1\n";
  const std::string dir =
      WriteTumFolder(tmp, "0.99 rgb/1.png\n1.5 rgb/2.png\n2.01 rgb/3.png\n3.0 rgb/4.png\n", &gt);
  TumOptions options;
  options.max_time_difference = 0.5;
  const std::vector<Frame> frames = ReadTumSequence(dir, options);
  ASSERT_EQ(frames.size(), 4u);
  ASSERT_TRUE(frames[0].pose && frames[1].pose && frames[2].pose);
  EXPECT_EQ(frames[0].pose->translation.x(), 1.0);
  EXPECT_EQ(frames[1].pose->translation.x(), 1.0);  // tie: the earlier pose
  EXPECT_EQ(frames[2].pose->translation.x(), 2.0);
  EXPECT_FALSE(frames[3].pose.has_value());  // 1 s after the last pose
}

TEST(TumTest, MissingGroundTruthMeansPoseless) {
  TempDir tmp;
  const std::string dir = WriteTumFolder(tmp, "# rgb\n1.0 rgb/1.png\n2.0 rgb/2.png\n", nullptr);
  const std::vector<Frame> frames = ReadTumSequence(dir);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_FALSE(frames[0].pose.has_value());
  EXPECT_FALSE(frames[1].pose.has_value());
  EXPECT_DOUBLE_EQ(frames[1].timestamp, 2.0);
}

TEST(TumTest, NormalisesNearlyUnitQuaternions) {
  TempDir tmp;
  const std::string path = tmp.Write("gt.txt", "1.0 0 0 0 0 0 0.6 0.804\n");  // norm 1.0032
  const std::vector<TumPoseStamped> poses = ReadTumTrajectory(path);
  ASSERT_EQ(poses.size(), 1u);
  EXPECT_NEAR(poses[0].pose.rotation.norm(), 1.0, 1e-12);
  EXPECT_NEAR(poses[0].pose.rotation.z(), 0.6 / std::hypot(0.6, 0.804), 1e-12);
}

TEST(TumTest, MalformedTrajectoryLinesNameFileAndLine) {
  TempDir tmp;
  const std::string header = "# ground truth\n# timestamp tx ty tz qx qy qz qw\n";
  const std::string good = "1.0 0 0 0 0 0 0 1\n";
  const std::string short_line =
      tmp.Write("short/groundtruth.txt", header + good + "2.0 1 2 3 4\n");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadTumTrajectory(short_line); },
                                          {short_line + ":4:", "expected 8 numbers", "got 5"}));
  const std::string text = tmp.Write("text/groundtruth.txt", header + "1.0 0 0 abc 0 0 0 1\n");
  EXPECT_TRUE(
      ThrowsWith<InvalidArgument>([&] { ReadTumTrajectory(text); }, {text + ":3:", "'abc'", "tz"}));
  const std::string non_unit =
      tmp.Write("quat/groundtruth.txt", good + good + "3.0 0 0 0 0 0 0 0.9\n");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadTumTrajectory(non_unit); },
                                          {non_unit + ":3:", "quaternion"}));
  const std::string nan = tmp.Write("nan/groundtruth.txt", "nan 0 0 0 0 0 0 1\n");
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadTumTrajectory(nan); }, {nan + ":1:"}));
  EXPECT_TRUE(ThrowsWith<NotFound>([&] { ReadTumTrajectory(tmp.Path("none.txt")); }, {"none.txt"}));

  // The same errors surface through ReadTumSequence.
  const std::string bad_gt = header + good + "2.0 1 2 3 4\n";
  TempDir seq;
  const std::string dir = WriteTumFolder(seq, "1.0 rgb/1.png\n", &bad_gt);
  EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadTumSequence(dir); },
                                          {"groundtruth.txt:4:", "expected 8 numbers"}));
}

TEST(TumTest, MalformedRgbListNamesFileAndLine) {
  {
    TempDir tmp;
    const std::string dir =
        WriteTumFolder(tmp, "# rgb\n1.0 rgb/1.png\n2.0 rgb/2.png extra\n", nullptr);
    EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadTumSequence(dir); },
                                            {"rgb.txt:3:", "expected 2 fields", "got 3"}));
  }
  {
    TempDir tmp;
    const std::string dir = WriteTumFolder(tmp, "1.0 rgb/1.png\n1.x rgb/2.png\n", nullptr);
    EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadTumSequence(dir); },
                                            {"rgb.txt:2:", "timestamp", "'1.x'"}));
  }
  {
    TempDir tmp;
    const std::string dir = WriteTumFolder(tmp, "1.0 rgb/1.png\n\n2.0 rgb/9.png\n", nullptr);
    // A listed image that is missing is kept (ids are positions in rgb.txt);
    // the build skips it as unreadable and counts it.
    const auto frames = ReadTumSequence(dir);
    ASSERT_EQ(frames.size(), 2u);
    EXPECT_EQ(frames[1].id, 2);
    EXPECT_NE(frames[1].image_path.find("9.png"), std::string::npos);
  }
  {
    TempDir tmp;
    const std::string dir = WriteTumFolder(tmp, "# only a comment\n", nullptr);
    EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { ReadTumSequence(dir); }, {"no frames"}));
  }
}

TEST(TumTest, MissingFolderAndBadOptions) {
  TempDir tmp;
  EXPECT_TRUE(
      ThrowsWith<NotFound>([&] { ReadTumSequence(tmp.Path("nowhere")); }, {tmp.Path("nowhere")}));
  EXPECT_TRUE(ThrowsWith<NotFound>([&] { ReadTumSequence(tmp.Path()); }, {"rgb.txt", tmp.Path()}));
  TumOptions options;
  options.max_time_difference = -1.0;
  EXPECT_FALSE(options.Check().empty());
  EXPECT_TRUE(ThrowsWith<InvalidArgument>(
      [&] { ReadTumSequence(kData + "/tum_fr2_pioneer_mini", options); }, {"max_time_diff"}));
  EXPECT_TRUE(TumOptions().Check().empty());
}

}  // namespace
}  // namespace placedb
