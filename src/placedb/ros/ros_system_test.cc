// The paper's Fig. 3 on ROS, on loopback: a master on a free port with its
// own ROS_HOME and log folder, the feed, N workers and the voter as separate
// processes, each test in its own namespace. Everything started is stopped by
// PID with SIGTERM (SIGKILL only after 5 s).
#include <gtest/gtest.h>
#include <placedb_msgs/PartialResult.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <signal.h>
#include <sys/wait.h>
#include <tf2_msgs/TFMessage.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>
#include <thread>

#include "placedb/dataset/image_folder.h"
#include "placedb/index/builder.h"
#include "placedb/index/place_database.h"
#include "placedb/ros/image_conversion.h"
#include "placedb/ros/messages.h"
#include "placedb/ros/testbed.h"
#include "placedb/util/file_io.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

const std::string kImages = PLACEDB_DATA_DIR "/rtabmap_loop/images";
const std::string kNodes = std::string(PLACEDB_ROS_TREE) + "/lib/placedb/";


// The master, shared by all tests, and this process as a ROS node (to send
// hostile messages); each test's nodes run in their own namespace.
class RosSystemTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() / ("placedb_ros_" + std::to_string(::getpid())));
    fs::remove_all(*dir_);
    ros_ = new LoopbackRos(dir_->string(), kNodes);
    // The database every test uses: images 1-40.
    BuildOptions build;
    build.threads = 2;
    build.progress = false;
    BuildDatabase(ListImageFolder(kImages, 1, 40), build, Db(), "rtabmap 1..40");
    int argc = 1;
    char name[] = "ros_system_test";
    char* argv[] = {name, nullptr};
    ros::init(argc, argv, "ros_system_test", ros::init_options::NoSigintHandler);
    for (int i = 0; i < 100 && !ros::master::check(); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    ASSERT_TRUE(ros::master::check()) << "rosmaster did not start on port " << ros_->port();
  }
  static void TearDownTestSuite() {
    ros::shutdown();
    delete ros_;
    fs::remove_all(*dir_);
    delete dir_;
  }
  void TearDown() override { ros_->StopNodes(); }

  static std::string Db() { return (*dir_ / "db").string(); }
  static std::string Path(const std::string& name) { return (*dir_ / name).string(); }
  static pid_t Start(const std::vector<std::string>& args, const std::string& log,
                     const std::string& ns) {
    return ros_->Start(args, log, ns);
  }
  static int WaitExit(pid_t pid, double seconds) { return LoopbackRos::WaitExit(pid, seconds); }
  static bool Alive(pid_t pid) { return LoopbackRos::Alive(pid); }
  static std::string ReadLog(const std::string& log) { return ros_->ReadLog(log); }
  // Waits until `count` nodes subscribe to `topic` (registered at the master).
  static bool WaitSubscribers(const std::string& topic, int count, double seconds) {
    const auto until = Clock::now() + std::chrono::duration<double>(seconds);
    while (Clock::now() < until) {
      XmlRpc::XmlRpcValue args, result, payload;
      args[0] = ros::this_node::getName();
      if (ros::master::execute("getSystemState", args, result, payload, true)) {
        for (int i = 0; i < payload[1].size(); ++i) {
          if (std::string(payload[1][i][0]) == topic && payload[1][i][1].size() >= count)
            return true;
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return false;
  }

  // What the single-process query answers for frames 41..84.
  static std::vector<QueryResult> SingleProcess(const QueryOptions& options) {
    const PlaceDatabase db = PlaceDatabase::Open(Db());
    std::vector<QueryResult> out;
    for (const Frame& f : ListImageFolder(kImages, 41, 84))
      out.push_back(db.Query(LoadFrameImage(f), options));
    return out;
  }

  static fs::path* dir_;
  static LoopbackRos* ros_;
};
fs::path* RosSystemTest::dir_ = nullptr;
LoopbackRos* RosSystemTest::ros_ = nullptr;

void ExpectSameAnswer(const nlohmann::json& line, const QueryResult& expected,
                      const std::string& what) {
  const QueryResult got = line["result"].get<QueryResult>();
  ASSERT_EQ(got.ranked.size(), expected.ranked.size()) << what;
  for (size_t i = 0; i < got.ranked.size(); ++i) {
    EXPECT_EQ(got.ranked[i].keyframe_id, expected.ranked[i].keyframe_id) << what << " rank " << i;
    EXPECT_EQ(got.ranked[i].score, expected.ranked[i].score) << what << " rank " << i;
    EXPECT_EQ(got.ranked[i].num_matches, expected.ranked[i].num_matches) << what << " rank " << i;
  }
  EXPECT_EQ(got.matched, expected.matched) << what;
}

// Feed + 3 workers (interleaved partitions, pinned round-robin to the CPUs)
// + voter: every frame's answer is complete and equals the single-process
// query of the same image.
TEST_F(RosSystemTest, AnswersEqualTheSingleProcessQuery) {
  const std::string ns = "/full";
  Start({"placedb_voter", "--db", Db(), "--partitions", "3", "--partition-scheme", "interleaved",
         "--deadline-ms", "3000", "--answers-file", Path("full_answers.jsonl")},
        "full_voter.log", ns);
  for (int i = 0; i < 3; ++i) {
    Start({"placedb_worker", "--db", Db(), "--partition", std::to_string(i) + "/3",
           "--partition-scheme", "interleaved", "--cpu", std::to_string(i % 2)},
          "full_worker" + std::to_string(i) + ".log", ns);
  }
  ASSERT_TRUE(WaitSubscribers(ns + "/partial_results", 1, 30));
  const pid_t feed = Start({"placedb_feed", "--images", kImages, "--first", "41", "--wait-for", "3",
                            "--rate", "0", "--log-file", Path("full_feed.jsonl")},
                           "full_feed.log", ns);
  ASSERT_EQ(WaitExit(feed, 240), 0) << ReadLog("full_feed.log");
  const std::vector<nlohmann::json> answers = placedb::LoopbackRos::ReadJsonLines(Path("full_answers.jsonl"));
  ASSERT_EQ(answers.size(), 44u) << ReadLog("full_voter.log");
  const std::vector<QueryResult> expected = SingleProcess(QueryOptions());
  for (const nlohmann::json& a : answers) {
    const uint64_t seq = a["frame_seq"];
    ASSERT_LT(seq, 44u);
    EXPECT_TRUE(a["complete"].get<bool>()) << "frame " << seq;
    ExpectSameAnswer(a, expected[seq], "frame " + std::to_string(seq));
  }
  for (int i = 0; i < 3; ++i) {
    EXPECT_NE(ReadLog("full_worker" + std::to_string(i) + ".log")
                  .find("pinned to CPU " + std::to_string(i % 2)),
              std::string::npos);
  }
}

// The same through one extractor node: the workers only match.
TEST_F(RosSystemTest, WorkersOnExtractedFeatures) {
  const std::string ns = "/features";
  Start({"placedb_voter", "--db", Db(), "--partitions", "2", "--deadline-ms", "3000",
         "--answers-file", Path("features_answers.jsonl")},
        "features_voter.log", ns);
  Start({"placedb_extractor", "--db", Db()}, "features_extractor.log", ns);
  for (int i = 0; i < 2; ++i) {
    Start({"placedb_worker", "--db", Db(), "--partition", std::to_string(i) + "/2", "--input",
           "features"},
          "features_worker" + std::to_string(i) + ".log", ns);
  }
  ASSERT_TRUE(WaitSubscribers(ns + "/features", 2, 30));
  const pid_t feed = Start({"placedb_feed", "--images", kImages, "--first", "41", "--last", "56",
                            "--wait-for", "1", "--rate", "0"},
                           "features_feed.log", ns);
  ASSERT_EQ(WaitExit(feed, 120), 0) << ReadLog("features_feed.log");
  const std::vector<nlohmann::json> answers = placedb::LoopbackRos::ReadJsonLines(Path("features_answers.jsonl"));
  ASSERT_EQ(answers.size(), 16u) << ReadLog("features_voter.log");
  const std::vector<QueryResult> expected = SingleProcess(QueryOptions());
  for (const nlohmann::json& a : answers) {
    EXPECT_TRUE(a["complete"].get<bool>());
    ExpectSameAnswer(a, expected[a["frame_seq"].get<uint64_t>()], "frame");
  }
}

// A worker killed (SIGKILL) mid-run does not stop the system: later frames
// are answered within the deadline, flagged partial and naming the missing
// partition; restarted, the worker rejoins and answers are complete again.
// Every published frame is answered exactly once.
TEST_F(RosSystemTest, AKilledWorkerIsAnsweredAroundAndRejoins) {
  const std::string ns = "/faults";
  const double deadline_ms = 400;
  Start({"placedb_voter", "--db", Db(), "--partitions", "3", "--deadline-ms", "400",
         "--answers-file", Path("faults_answers.jsonl")},
        "faults_voter.log", ns);
  std::vector<pid_t> workers;
  auto worker = [&](int i) {
    return Start({"placedb_worker", "--db", Db(), "--partition", std::to_string(i) + "/3"},
                 "faults_worker" + std::to_string(i) + ".log", ns);
  };
  for (int i = 0; i < 3; ++i) workers.push_back(worker(i));
  ASSERT_TRUE(WaitSubscribers(ns + "/image", 3, 30));
  // 8 frames a second for 132 frames (three loops of 41-84), ~17 s.
  const pid_t feed =
      Start({"placedb_feed", "--images", kImages, "--first", "41", "--rate", "8", "--loops", "3",
             "--wait-for", "3", "--log-file", Path("faults_feed.jsonl")},
            "faults_feed.log", ns);
  auto answers_so_far = [&] { return placedb::LoopbackRos::ReadJsonLines(Path("faults_answers.jsonl")).size(); };
  auto wait_answers = [&](size_t n) {
    for (int i = 0; i < 600 && answers_so_far() < n; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
  };
  wait_answers(30);
  ::kill(workers[1], SIGKILL);
  const size_t killed_at = answers_so_far();
  wait_answers(killed_at + 25);
  worker(1);  // restarted: rejoins
  const size_t restarted_at = answers_so_far();
  ASSERT_EQ(WaitExit(feed, 120), 0) << ReadLog("faults_feed.log");
  std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<int>(deadline_ms) + 300));
  const std::vector<nlohmann::json> answers = placedb::LoopbackRos::ReadJsonLines(Path("faults_answers.jsonl"));
  const std::vector<nlohmann::json> published = placedb::LoopbackRos::ReadJsonLines(Path("faults_feed.jsonl"));
  ASSERT_EQ(published.size(), 132u);
  std::set<uint64_t> seqs;
  int partial_after_kill = 0, complete_at_end = 0;
  for (size_t i = 0; i < answers.size(); ++i) {
    const nlohmann::json& a = answers[i];
    EXPECT_TRUE(seqs.insert(a["frame_seq"].get<uint64_t>()).second)
        << "answered twice: " << a["frame_seq"];
    EXPECT_LE(a["wait_ms"].get<double>(), deadline_ms + 100) << "frame " << a["frame_seq"];
    if (i > killed_at + 3 && i < restarted_at && !a["complete"].get<bool>()) {
      ++partial_after_kill;
      EXPECT_EQ(a["missing"], nlohmann::json::array({1})) << a.dump();
    }
    if (i + 20 >= answers.size()) complete_at_end += a["complete"].get<bool>();
  }
  EXPECT_EQ(seqs.size(), 132u) << "every published frame is answered once";
  EXPECT_GE(partial_after_kill, 15)
      << "frames without the killed worker are answered, flagged partial";
  EXPECT_GE(complete_at_end, 18) << "the restarted worker rejoins";
}

// Malformed messages are dropped and logged once per cause; the nodes live
// on and keep answering good frames.
TEST_F(RosSystemTest, MalformedMessagesAreDroppedOncePerCause) {
  const std::string ns = "/hostile";
  const pid_t voter = Start({"placedb_voter", "--db", Db(), "--partitions", "1", "--deadline-ms",
                             "500", "--answers-file", Path("hostile_answers.jsonl")},
                            "hostile_voter.log", ns);
  const pid_t image_worker =
      Start({"placedb_worker", "--db", Db(), "--partition", "0/1"}, "hostile_worker.log", ns);
  const pid_t features_worker = Start({"placedb_worker", "--db", Db(), "--partition", "0/1",
                                       "--input", "features", "__name:=features_worker"},
                                      "hostile_features_worker.log", ns);
  ros::NodeHandle nh(ns);
  ros::Publisher images = nh.advertise<sensor_msgs::Image>("image", 10);
  ros::Publisher features = nh.advertise<placedb_msgs::Features>("features", 10);
  ros::Publisher partials = nh.advertise<placedb_msgs::PartialResult>("partial_results", 10);
  ros::Publisher frames = nh.advertise<std_msgs::Header>("frames", 10);
  // Connected, not just registered: publishers count their live links.
  for (const ros::Publisher* p : {&images, &features, &partials, &frames}) {
    for (int i = 0; i < 600 && p->getNumSubscribers() < 1; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    ASSERT_GE(p->getNumSubscribers(), 1u) << p->getTopic();
  }
  const cv::Mat good = cv::imread(testing_util::RtabmapImage(42));
  std_msgs::Header h;
  sensor_msgs::Image wrong_encoding = BgrToImageMessage(good, h);
  wrong_encoding.encoding = "16UC1";
  sensor_msgs::Image huge = BgrToImageMessage(good, h);
  huge.width = 100000;
  sensor_msgs::Image short_data = BgrToImageMessage(good, h);
  short_data.data.resize(100);
  placedb_msgs::PartialResult unknown_partition;
  unknown_partition.database_id = PlaceDatabase::Open(Db()).database().keyframes_file();
  unknown_partition.partition = 5;
  unknown_partition.num_partitions = 1;
  unknown_partition.scheme = "contiguous";
  placedb_msgs::PartialResult other_db = unknown_partition;
  other_db.database_id = "keyframes.0000000000000000.bin";
  placedb_msgs::Features surf;
  surf.feature_type = "surf";
  surf.descriptor_bytes = 256;
  surf.keypoints = std::vector<float>(7, 1.0f);
  surf.descriptors = std::vector<uint8_t>(256, 0);
  placedb_msgs::Features broken = surf;
  broken.feature_type = "orb";
  broken.descriptor_bytes = 32;
  // Spaced out: a worker keeps only the newest frame when it is busy.
  auto pause = [] { std::this_thread::sleep_for(std::chrono::milliseconds(40)); };
  for (int repeat = 0; repeat < 5; ++repeat) {
    images.publish(wrong_encoding);
    features.publish(surf);
    partials.publish(unknown_partition);
    pause();
    images.publish(huge);
    features.publish(broken);
    partials.publish(other_db);
    pause();
    images.publish(short_data);
    pause();
  }
  // A good frame after all that is answered. (roscpp numbers each
  // publisher's messages: 15 bad images went before it, so it is frame 15
  // for the worker, while its announcement is the first, frame 0.)
  frames.publish(h);
  images.publish(BgrToImageMessage(good, h));
  for (int i = 0; i < 100 && placedb::LoopbackRos::ReadJsonLines(Path("hostile_answers.jsonl")).empty(); ++i) {
    if (i % 10 == 9) {  // resend until the voter answers (connections may still be settling)
      frames.publish(h);
      images.publish(BgrToImageMessage(good, h));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  EXPECT_TRUE(Alive(voter));
  EXPECT_TRUE(Alive(image_worker));
  EXPECT_TRUE(Alive(features_worker));
  const std::vector<nlohmann::json> answers = placedb::LoopbackRos::ReadJsonLines(Path("hostile_answers.jsonl"));
  ASSERT_FALSE(answers.empty()) << ReadLog("hostile_voter.log");
  bool good_answered = false;
  for (const nlohmann::json& a : answers) {
    const QueryResult r = a["result"].get<QueryResult>();
    // Image 42 shows the place of keyframes 1-4.
    if (r.best() != nullptr && r.best()->keyframe_id >= 1 && r.best()->keyframe_id <= 4)
      good_answered = true;
  }
  EXPECT_TRUE(good_answered) << answers.size() << " answers, first " << answers[0].dump() << "\n"
                             << ReadLog("hostile_worker.log") << ReadLog("hostile_voter.log");
  auto count = [](const std::string& text, const std::string& part) {
    size_t n = 0;
    for (size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++n;
    return n;
  };
  const std::string worker_log = ReadLog("hostile_worker.log");
  EXPECT_EQ(count(worker_log, "(image encoding"), 1u) << worker_log;
  EXPECT_EQ(count(worker_log, "(image size"), 1u) << worker_log;
  EXPECT_EQ(count(worker_log, "(image data"), 1u) << worker_log;
  const std::string voter_log = ReadLog("hostile_voter.log");
  EXPECT_EQ(count(voter_log, "(database"), 1u) << voter_log;
  EXPECT_EQ(count(voter_log, "(partition"), 1u) << voter_log;
  const std::string features_log = ReadLog("hostile_features_worker.log");
  EXPECT_EQ(count(features_log, "(the query has surf features"), 1u) << features_log;
  EXPECT_EQ(count(features_log, "(descriptors"), 1u) << features_log;
}

// roslaunch with the shipped launch file: a voter, two workers and a feed on
// one machine, found as the ROS package "placedb" in the build tree.
TEST_F(RosSystemTest, TheLaunchFileRunsTheSystem) {
  const std::string tree = PLACEDB_ROS_TREE;
  ::setenv("ROS_PACKAGE_PATH", (tree + "/share").c_str(), 1);
  const char* prefix = std::getenv("CMAKE_PREFIX_PATH");
  ::setenv("CMAKE_PREFIX_PATH", (tree + (prefix ? std::string(":") + prefix : "")).c_str(), 1);
  const pid_t launch = Start(
      {"roslaunch", "placedb", "placedb.launch", "db:=" + Db(), "workers:=2", "images:=" + kImages,
       "answers_file:=" + Path("launch_answers.jsonl"), "feed_args:=--rate 0 --first 70"},
      "launch.log", "/launched");
  // The feed is required: when it has published its frames, roslaunch ends.
  EXPECT_EQ(WaitExit(launch, 240), 0) << ReadLog("launch.log");
  const std::vector<nlohmann::json> answers = placedb::LoopbackRos::ReadJsonLines(Path("launch_answers.jsonl"));
  ASSERT_EQ(answers.size(), 15u) << ReadLog("launch.log");
  const std::vector<QueryResult> expected = SingleProcess(QueryOptions());
  for (const nlohmann::json& a : answers) {
    EXPECT_TRUE(a["complete"].get<bool>());
    ExpectSameAnswer(a, expected[29 + a["frame_seq"].get<uint64_t>()], "launched frame");
  }
}

// placedb build --bag: a bag written here from the sample images (raw and
// PNG-compressed frames, poses on /tf) builds the database the image folder
// builds, with poses.
TEST_F(RosSystemTest, BuildFromABag) {
  const std::vector<Frame> frames = ListImageFolder(kImages, 1, 8);
  for (const bool compressed : {false, true}) {
    const std::string bag_path = Path(compressed ? "compressed.bag" : "raw.bag");
    {
      rosbag::Bag bag(bag_path, rosbag::bagmode::Write);
      for (size_t i = 0; i < frames.size(); ++i) {
        std_msgs::Header h;
        h.seq = static_cast<uint32_t>(i);
        h.stamp = ros::Time(100.0 + 0.5 * i);
        h.frame_id = "camera";
        const cv::Mat image = cv::imread(frames[i].image_path);
        if (compressed) {
          sensor_msgs::CompressedImage c;
          c.header = h;
          c.format = "png";
          cv::imencode(".png", image, c.data);
          bag.write("/camera/image", h.stamp, c);
        } else {
          bag.write("/camera/image", h.stamp, BgrToImageMessage(image, h));
        }
        tf2_msgs::TFMessage tf;
        geometry_msgs::TransformStamped t;
        t.header.stamp = h.stamp;
        t.header.frame_id = "world";
        t.child_frame_id = "camera";
        t.transform.translation.x = 0.1 * i;
        t.transform.rotation.w = 1.0;
        tf.transforms.push_back(t);
        bag.write("/tf", h.stamp, tf);
      }
    }
    const std::string db = Path(compressed ? "bag_db_compressed" : "bag_db");
    const std::string cmd = std::string(PLACEDB_BINARY) + " build --bag " + bag_path +
                            " --topic /camera/image --bag-tf world,camera --out " + db +
                            " --quiet > " + Path("bag_build.log") + " 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << ReadLog("bag_build.log");
    const Database from_bag = Database::Load(db);
    BuildOptions options;
    options.progress = false;
    BuildDatabase(frames, options, Path("folder_db"), "folder");
    const Database from_folder = Database::Load(Path("folder_db"));
    fs::remove_all(Path("folder_db"));
    ASSERT_EQ(from_bag.size(), 8u);
    EXPECT_EQ(from_bag.num_features(), from_folder.num_features());
    for (size_t i = 0; i < 8; ++i) {
      ASSERT_EQ(from_bag.FeatureCount(i), from_folder.FeatureCount(i));
      const DescriptorBlock a = from_bag.Descriptors(i), b = from_folder.Descriptors(i);
      EXPECT_EQ(0, std::memcmp(a.data, b.data, static_cast<size_t>(a.rows) * a.row_bytes)) << i;
      ASSERT_TRUE(from_bag.keyframe(i).pose.has_value());
      EXPECT_NEAR(from_bag.keyframe(i).pose->translation.x(), 0.1 * i, 1e-9);
      EXPECT_NEAR(from_bag.keyframe(i).timestamp, 100.0 + 0.5 * i, 1e-6);
    }
    EXPECT_NE(from_bag.info()["source"].get<std::string>().find("bag:"), std::string::npos);
  }
  // A topic without images and a missing bag are clear errors.
  const std::string cmd = std::string(PLACEDB_BINARY) + " build --bag " + Path("raw.bag") +
                          " --topic /nothing --out " + Path("none_db") + " > " +
                          Path("bag_err.log") + " 2>&1";
  EXPECT_NE(std::system(cmd.c_str()), 0);
  EXPECT_NE(ReadLog("bag_err.log").find("no sensor_msgs/Image"), std::string::npos)
      << ReadLog("bag_err.log");
}

}  // namespace
}  // namespace placedb
