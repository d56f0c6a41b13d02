// placedb's ROS messages: round trips, and every malformed message a node can
// receive is a clear InvalidArgument with its cause, never a bad read.
#include "placedb/ros/messages.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <opencv2/imgcodecs.hpp>

#include "placedb/dataset/bag/image_message.h"
#include "placedb/feature/extractor.h"
#include "placedb/feature/testing.h"
#include "placedb/ros/node_common.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
using testing_util::ThrowsWith;

TEST(RosMessagesTest, FeaturesRoundTrip) {
  const cv::Mat image = cv::imread(testing_util::RtabmapImage(42));
  ExtractorOptions surf = testing::ModelFreeExtractorOptions();
  surf.type = FeatureType::kSurf;
  surf.surf.max_features = 100;
  for (const ExtractorOptions& options : {testing::ModelFreeExtractorOptions(), surf}) {
    const FeatureSet f = FeatureExtractor::Create(options)->Extract(image);
    ASSERT_FALSE(f.empty());
    std_msgs::Header h;
    h.seq = 17;
    const placedb_msgs::Features m = FeaturesToMessage(f, 17, h);
    EXPECT_EQ(m.frame_seq, 17u);
    const FeatureSet back = FeaturesFromMessage(m);
    EXPECT_EQ(back.type, f.type);
    testing_util::ExpectSameKeypoints(back.keypoints, f.keypoints);
    EXPECT_EQ(cv::norm(back.descriptors, f.descriptors, cv::NORM_INF), 0.0);
    // The whole-image row travels too (the workers score the channel).
    ASSERT_FALSE(f.whole_image.empty());
    ASSERT_EQ(back.whole_image.type(), CV_8SC1);
    ASSERT_EQ(back.whole_image.cols, f.whole_image.cols);
    EXPECT_EQ(std::memcmp(back.whole_image.data, f.whole_image.data, f.whole_image.cols), 0);
  }
  // No features at all is fine.
  FeatureSet empty;
  empty.descriptors = cv::Mat(0, 32, CV_8U);
  EXPECT_TRUE(FeaturesFromMessage(FeaturesToMessage(empty, 1, std_msgs::Header())).empty());
}

TEST(RosMessagesTest, MalformedFeaturesAreRefused) {
  const FeatureSet f = FeatureExtractor::Create(testing::ModelFreeExtractorOptions())
                           ->Extract(cv::imread(testing_util::RtabmapImage(42)));
  const placedb_msgs::Features good = FeaturesToMessage(f, 1, std_msgs::Header());
  auto fails = [&](const std::function<void(placedb_msgs::Features&)>& edit,
                   const std::string& cause) {
    placedb_msgs::Features m = good;
    edit(m);
    return ThrowsWith<InvalidArgument>([&] { FeaturesFromMessage(m); }, cause);
  };
  EXPECT_TRUE(fails([](auto& m) { m.feature_type = "sift"; }, "feature type"));
  EXPECT_TRUE(fails([](auto& m) { m.descriptor_bytes = 16; }, "descriptor width"));
  EXPECT_TRUE(fails([](auto& m) { m.keypoints.pop_back(); }, "keypoints"));
  EXPECT_TRUE(fails([](auto& m) { m.descriptors.pop_back(); }, "descriptors"));
  EXPECT_TRUE(fails([](auto& m) { m.keypoints[3] = std::nanf(""); }, "keypoints"));
  EXPECT_TRUE(fails([](auto& m) { m.keypoints[5] = 1.5f; }, "keypoints"));
  EXPECT_TRUE(fails(
      [](auto& m) {
        m.feature_type = "surf";
        m.descriptor_bytes = 256;
      },
      "descriptors"));
}

TEST(RosMessagesTest, PartialResultsRoundTripAndAreChecked) {
  QueryResult r;
  RankedKeyframe k;
  k.keyframe_id = 4;
  k.num_matches = 30;
  k.num_inliers = 25;
  k.score = 25;
  r.ranked = {k};
  r.num_keyframes = 13;
  r.num_examined = 13;
  r.num_verified = 1;
  r.times.match_ms = 1.5;
  const placedb_msgs::PartialResult m = PartialToMessage(
      r, 9, std_msgs::Header(), KeyframeSubset::Partition(1, 3), "keyframes.x.bin");
  EXPECT_EQ(m.partition, 1u);
  EXPECT_EQ(m.num_partitions, 3u);
  EXPECT_EQ(m.scheme, "contiguous");
  const QueryResult back = PartialFromMessage(m);
  EXPECT_EQ(back.ranked, r.ranked);
  EXPECT_EQ(back.num_keyframes, 13u);
  auto fails = [&](const std::function<void(placedb_msgs::PartialResult&)>& edit,
                   const std::string& cause) {
    placedb_msgs::PartialResult bad = m;
    edit(bad);
    return ThrowsWith<InvalidArgument>([&] { PartialFromMessage(bad); }, cause);
  };
  EXPECT_TRUE(fails([](auto& b) { b.partition = 3; }, "partition"));
  EXPECT_TRUE(fails([](auto& b) { b.num_partitions = 0; }, "partition"));
  EXPECT_TRUE(fails([](auto& b) { b.scheme = "random"; }, "scheme"));
  EXPECT_TRUE(fails([](auto& b) { b.ranked[0].num_inliers = 31; }, "ranked keyframe"));
  EXPECT_TRUE(fails([](auto& b) { b.ranked[0].score = std::nan(""); }, "ranked keyframe"));
  EXPECT_TRUE(fails([](auto& b) { b.ranked[0].score = 99; }, "ranked keyframe"));
  EXPECT_TRUE(fails([](auto& b) { b.match_ms = -1; }, "times"));
  // With the whole-image channel: its values travel, the score may exceed
  // the counts by the bonus (the voter checks the bonus), and bad values are
  // refused.
  EXPECT_TRUE(std::isnan(m.ranked[0].whole_image));
  QueryResult whole = r;
  whole.ranked[0].whole_image = 0.75;
  whole.ranked[0].whole_image_z = 4.5;
  whole.ranked[0].score = 25 + 15;
  const placedb_msgs::PartialResult w = PartialToMessage(
      whole, 9, std_msgs::Header(), KeyframeSubset::Partition(1, 3), "keyframes.x.bin");
  EXPECT_EQ(PartialFromMessage(w).ranked, whole.ranked);
  auto whole_fails = [&](const std::function<void(placedb_msgs::PartialResult&)>& edit) {
    placedb_msgs::PartialResult bad = w;
    edit(bad);
    return ThrowsWith<InvalidArgument>([&] { PartialFromMessage(bad); }, "ranked keyframe");
  };
  EXPECT_TRUE(whole_fails([](auto& b) { b.ranked[0].whole_image_z = std::nan(""); }));
  EXPECT_TRUE(whole_fails([](auto& b) { b.ranked[0].whole_image = 1.5; }));
  EXPECT_TRUE(whole_fails([](auto& b) { b.ranked[0].whole_image_z = INFINITY; }));
  EXPECT_TRUE(whole_fails([](auto& b) { b.ranked[0].score = 20; }));
}

// The two rounds of bag-of-words search: a worker's shortlist and the
// voter's candidates go over and back whole, and malformed ones are refused.
TEST(RosMessagesTest, ShortlistsAndCandidatesRoundTripAndAreChecked) {
  Shortlist s;
  s.bow = {{7, 8, 0.25, 12}, {3, 4, 0.125, -1}};
  s.whole_image = {{9, 10, 0.5, -1}};
  s.deadline_reached = true;
  s.retrieve_ms = 2.5;
  const placedb_msgs::Shortlist m =
      ShortlistToMessage(s, 9, std_msgs::Header(),
                         KeyframeSubset::Partition(2, 3, PartitionScheme::kInterleaved), "k.bin");
  EXPECT_EQ(m.partition, 2u);
  EXPECT_EQ(m.num_partitions, 3u);
  EXPECT_EQ(m.scheme, "interleaved");
  EXPECT_EQ(m.frame_seq, 9u);
  const Shortlist back = ShortlistFromMessage(m);
  EXPECT_EQ(back.bow, s.bow);
  EXPECT_EQ(back.whole_image, s.whole_image);
  EXPECT_TRUE(back.deadline_reached);
  EXPECT_EQ(back.retrieve_ms, 2.5);
  auto fails = [&](const std::function<void(placedb_msgs::Shortlist&)>& edit,
                   const std::string& cause) {
    placedb_msgs::Shortlist bad = m;
    edit(bad);
    return ThrowsWith<InvalidArgument>([&] { ShortlistFromMessage(bad); }, cause);
  };
  EXPECT_TRUE(fails([](auto& b) { b.partition = 3; }, "partition"));
  EXPECT_TRUE(fails([](auto& b) { b.scheme = "random"; }, "scheme"));
  EXPECT_TRUE(fails([](auto& b) { b.bow[1].score = std::nan(""); }, "shortlist"));
  EXPECT_TRUE(fails([](auto& b) { b.whole_image[0].guided = -2; }, "shortlist"));
  EXPECT_TRUE(fails([](auto& b) { b.bow.resize(100001); }, "shortlist"));
  EXPECT_TRUE(fails([](auto& b) { b.retrieve_ms = -1; }, "times"));

  FrameCandidates c;
  c.frame_seq = 11;
  c.merged = {0, 2};
  c.candidates = s.bow;
  const placedb_msgs::Candidates cm =
      CandidatesToMessage(c, std_msgs::Header(), 3, PartitionScheme::kContiguous, "k.bin");
  EXPECT_EQ(cm.num_partitions, 3u);
  EXPECT_EQ(cm.scheme, "contiguous");
  const FrameCandidates cback = CandidatesFromMessage(cm);
  EXPECT_EQ(cback.frame_seq, 11u);
  EXPECT_EQ(cback.merged, c.merged);
  EXPECT_EQ(cback.candidates, c.candidates);
  auto refused = [&](const std::function<void(placedb_msgs::Candidates&)>& edit,
                     const std::string& cause) {
    placedb_msgs::Candidates bad = cm;
    edit(bad);
    return ThrowsWith<InvalidArgument>([&] { CandidatesFromMessage(bad); }, cause);
  };
  EXPECT_TRUE(refused([](auto& b) { b.num_partitions = 0; }, "partition"));
  EXPECT_TRUE(refused([](auto& b) { b.partitions = {0, 3}; }, "partition"));
  EXPECT_TRUE(refused([](auto& b) { b.partitions = {2, 0}; }, "partition"));
  EXPECT_TRUE(refused([](auto& b) { b.scheme = ""; }, "scheme"));
  EXPECT_TRUE(refused([](auto& b) { b.candidates[0].score = INFINITY; }, "candidates"));
}

TEST(RosMessagesTest, ImagesAreChecked) {
  const cv::Mat bgr = cv::imread(testing_util::RtabmapImage(1));
  std_msgs::Header h;
  const sensor_msgs::Image good = BgrToImageMessage(bgr, h);
  EXPECT_EQ(cv::norm(ImageMessageToBgr(good), bgr, cv::NORM_INF), 0.0);
  sensor_msgs::Image rgb = good;
  rgb.encoding = "rgb8";
  const cv::Mat swapped = ImageMessageToBgr(rgb);
  EXPECT_EQ(swapped.at<cv::Vec3b>(5, 5)[0], bgr.at<cv::Vec3b>(5, 5)[2]);
  auto fails = [&](const std::function<void(sensor_msgs::Image&)>& edit, const std::string& cause) {
    sensor_msgs::Image m = good;
    edit(m);
    return ThrowsWith<InvalidArgument>([&] { ImageMessageToBgr(m); }, cause);
  };
  EXPECT_TRUE(fails([](auto& m) { m.encoding = "16UC1"; }, "image encoding"));
  EXPECT_TRUE(fails([](auto& m) { m.width = 0; }, "image size"));
  EXPECT_TRUE(fails([](auto& m) { m.height = 100000; }, "image size"));
  EXPECT_TRUE(fails([](auto& m) { m.data.resize(10); }, "image data"));
  EXPECT_TRUE(fails([](auto& m) { m.step = 3; }, "image data"));
  EXPECT_TRUE(fails(
      [](auto& m) {
        m.data.clear();
        m.width = m.height = 0;
      },
      "image size"));
  EXPECT_EQ(ros_node::CauseOf("image data: 10 bytes"), "image data");
  EXPECT_EQ(ros_node::CauseOf("the query has surf features"), "the query has surf features");
  EXPECT_EQ(ros_node::CauseOf(std::string(100, 'x')), std::string(48, 'x'));
  // What the library throws has no source location in its message (it is in
  // where()), so the cause is the message's own first words.
  sensor_msgs::Image short_data = good;
  short_data.data.resize(10);
  try {
    ImageMessageToBgr(short_data);
    ADD_FAILURE() << "an image message with too few bytes was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_EQ(ros_node::CauseOf(e.what()), "image data");
    EXPECT_EQ(std::string(e.what()).find(".cc:"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace placedb
