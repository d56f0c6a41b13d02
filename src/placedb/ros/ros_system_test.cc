// The paper's Fig. 3 on ROS, on loopback: a master on a free port with its
// own ROS_HOME and log folder, the feed, N workers and the voter as separate
// processes, each test in its own namespace. Everything started is stopped by
// PID with SIGTERM (SIGKILL only after 5 s).
//
// Nothing here races a clock or asserts one, so a busy machine (ASan, other
// processes on the CPUs) changes how long the tests take, never their result:
// - a test waits for events (a node's link to another, as the publishing node
//   reports it; a line in an answers file), each with a generous limit that
//   only ends a hang;
// - a feed starts only when every link it depends on is up: it waits for one
//   image subscriber more than the system has, which this process adds last
//   (the gate);
// - a voter that must answer complete waits for every partition (no deadline
//   in reach), and the feed for each answer; deadlines are checked by what
//   they do (an answer flagged partial, naming the partition that is gone),
//   never by how long anything took.
#include <gtest/gtest.h>
#include <placedb_msgs/PartialResult.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <signal.h>
#include <std_msgs/String.h>
#include <sys/wait.h>
#include <tf2_msgs/TFMessage.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <thread>

#include "placedb/builder/builder.h"
#include "placedb/builder/testing.h"
#include "placedb/dataset/bag/image_message.h"
#include "placedb/dataset/image_folder.h"
#include "placedb/query/query.h"
#include "placedb/ros/messages.h"
#include "placedb/ros/system_testing.h"
#include "placedb/ros/testbed.h"
#include "placedb/session/place_database.h"
#include "placedb/util/file_io.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {
namespace fs = std::filesystem;

const std::string kImages = PLACEDB_DATA_DIR "/rtabmap_loop/images";
const std::string kNodes = std::string(PLACEDB_ROS_TREE) + "/lib/placedb/";
// What the system tests share (system_testing.h).
using ros_testing::ExpectSameAnswer;
using ros_testing::kLimit;
using ros_testing::kNoDeadline;
using ros_testing::kRunLimit;
using ros_testing::Linked;
using ros_testing::OpenGate;
using ros_testing::WaitLines;
using ros_testing::WaitLinked;
using ros_testing::WaitUntil;
using ros_testing::WrittenLines;

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
    ASSERT_TRUE(WaitUntil([] { return ros::master::check(); }))
        << "rosmaster did not start on port " << ros_->port();
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
  // What the single-process query answers for frames 41..84.
  static std::vector<QueryResult> SingleProcess(const QueryOptions& options) {
    return ros_testing::SingleProcess(Db(), kImages, 41, 84, options);
  }

  static fs::path* dir_;
  static LoopbackRos* ros_;
};
fs::path* RosSystemTest::dir_ = nullptr;
LoopbackRos* RosSystemTest::ros_ = nullptr;

// Feed + 3 workers (interleaved partitions, pinned round-robin to the CPUs)
// + voter: every frame's answer is complete and equals the single-process
// query of the same image. (The voter waits for every partition, the feed
// for each answer; the feed starts when every link is up.)
TEST_F(RosSystemTest, AnswersEqualTheSingleProcessQuery) {
  const std::string ns = "/full";
  Start({"placedb_voter", "--db", Db(), "--partitions", "3", "--partition-scheme", "interleaved",
         "--deadline-ms", kNoDeadline, "--answers-file", Path("full_answers.jsonl")},
        "full_voter.log", ns);
  for (int i = 0; i < 3; ++i) {
    Start({"placedb_worker", "--db", Db(), "--partition", std::to_string(i) + "/3",
           "--partition-scheme", "interleaved", "--cpu", std::to_string(i % 2)},
          "full_worker" + std::to_string(i) + ".log", ns);
  }
  // 3 workers + the gate.
  const pid_t feed =
      Start({"placedb_feed", "--images", kImages, "--first", "41", "--wait-for", "4", "--rate", "0",
             "--answer-timeout-ms", kNoDeadline, "--log-file", Path("full_feed.jsonl")},
            "full_feed.log", ns);
  ASSERT_TRUE(
      WaitLinked({ns + "/placedb_worker_0", ns + "/placedb_worker_1", ns + "/placedb_worker_2"},
                 ns + "/partial_results", {ns + "/placedb_voter"}))
      << ReadLog("full_voter.log") << ReadLog("full_worker0.log");
  ASSERT_TRUE(WaitLinked({ns + "/placedb_voter"}, ns + "/answers", {ns + "/placedb_feed"}))
      << ReadLog("full_feed.log");
  // The announcements on frames carry the frame's number, as its image does
  // (roscpp numbers only messages that contain a header: a bare
  // std_msgs/Header once went out with seq 0 for every frame).
  ros::CallbackQueue announcement_queue;
  ros::NodeHandle announcement_nh;
  announcement_nh.setCallbackQueue(&announcement_queue);
  std::vector<uint32_t> announced;
  const ros::Subscriber announcements = announcement_nh.subscribe<std_msgs::Header>(
      ns + "/frames", 100, [&](const std_msgs::HeaderConstPtr& h) { announced.push_back(h->seq); },
      ros::VoidConstPtr(), ros::TransportHints());
  ASSERT_TRUE(WaitLinked({ns + "/placedb_feed"}, ns + "/frames", {ros::this_node::getName()}));
  const ros::Subscriber gate = OpenGate(ns);
  ASSERT_EQ(WaitExit(feed, kRunLimit), 0) << ReadLog("full_feed.log");
  EXPECT_TRUE(WaitUntil([&] {
    announcement_queue.callAvailable();
    return announced.size() >= 44;
  }));
  ASSERT_EQ(announced.size(), 44u);
  for (uint32_t i = 0; i < announced.size(); ++i)
    EXPECT_EQ(announced[i], i) << "announcement " << i;
  const std::vector<nlohmann::json> answers = WaitLines(Path("full_answers.jsonl"), 44);
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
  Start({"placedb_voter", "--db", Db(), "--partitions", "2", "--deadline-ms", kNoDeadline,
         "--answers-file", Path("features_answers.jsonl")},
        "features_voter.log", ns);
  Start({"placedb_extractor", "--db", Db()}, "features_extractor.log", ns);
  for (int i = 0; i < 2; ++i) {
    Start({"placedb_worker", "--db", Db(), "--partition", std::to_string(i) + "/2", "--input",
           "features"},
          "features_worker" + std::to_string(i) + ".log", ns);
  }
  // The extractor + the gate.
  const pid_t feed = Start({"placedb_feed", "--images", kImages, "--first", "41", "--last", "56",
                            "--wait-for", "2", "--rate", "0", "--answer-timeout-ms", kNoDeadline},
                           "features_feed.log", ns);
  const std::vector<std::string> workers = {ns + "/placedb_worker_0", ns + "/placedb_worker_1"};
  ASSERT_TRUE(WaitLinked({ns + "/placedb_extractor"}, ns + "/features", workers))
      << ReadLog("features_extractor.log");
  ASSERT_TRUE(WaitLinked(workers, ns + "/partial_results", {ns + "/placedb_voter"}))
      << ReadLog("features_voter.log");
  ASSERT_TRUE(WaitLinked({ns + "/placedb_voter"}, ns + "/answers", {ns + "/placedb_feed"}))
      << ReadLog("features_feed.log");
  const ros::Subscriber gate = OpenGate(ns);
  ASSERT_EQ(WaitExit(feed, kRunLimit), 0) << ReadLog("features_feed.log");
  const std::vector<nlohmann::json> answers = WaitLines(Path("features_answers.jsonl"), 16);
  ASSERT_EQ(answers.size(), 16u) << ReadLog("features_voter.log");
  const std::vector<QueryResult> expected = SingleProcess(QueryOptions());
  for (const nlohmann::json& a : answers) {
    EXPECT_TRUE(a["complete"].get<bool>());
    ExpectSameAnswer(a, expected[a["frame_seq"].get<uint64_t>()], "frame");
  }
}

// Bag of words over 3 workers takes two rounds (shortlists, the voter's
// candidates, each worker's share): every answer is complete and equals the
// single-process bag-of-words query, with few candidates, where a
// partition's own best are often not the whole database's (the one-round
// merge differs on this data: PartitionWorkerTest).
TEST_F(RosSystemTest, BagOfWordsAnswersEqualTheSingleProcessQueryInTwoRounds) {
  const std::string ns = "/bow";
  const std::string db = Path("bow_db");
  testing_util::BuildSampleDatabase(db);
  const std::vector<std::string> search = {
      "--search", "bow", "--bow-candidates", "8", "--guided-candidates", "3"};
  std::vector<std::string> voter = {"placedb_voter",
                                    "--db",
                                    db,
                                    "--partitions",
                                    "3",
                                    "--partition-scheme",
                                    "interleaved",
                                    "--deadline-ms",
                                    kNoDeadline,
                                    "--answers-file",
                                    Path("bow_answers.jsonl")};
  voter.insert(voter.end(), search.begin(), search.end());
  Start(voter, "bow_voter.log", ns);
  std::vector<std::string> workers;
  for (int i = 0; i < 3; ++i) {
    std::vector<std::string> worker = {
        "placedb_worker",     "--db",       db, "--partition", std::to_string(i) + "/3",
        "--partition-scheme", "interleaved"};
    worker.insert(worker.end(), search.begin(), search.end());
    Start(worker, "bow_worker" + std::to_string(i) + ".log", ns);
    workers.push_back(ns + "/placedb_worker_" + std::to_string(i));
  }
  // 3 workers + the gate.
  const pid_t feed = Start({"placedb_feed", "--images", kImages, "--first", "41", "--wait-for", "4",
                            "--rate", "0", "--answer-timeout-ms", kNoDeadline},
                           "bow_feed.log", ns);
  ASSERT_TRUE(WaitLinked(workers, ns + "/shortlists", {ns + "/placedb_voter"}))
      << ReadLog("bow_voter.log") << ReadLog("bow_worker0.log");
  ASSERT_TRUE(WaitLinked({ns + "/placedb_voter"}, ns + "/candidates", workers))
      << ReadLog("bow_voter.log") << ReadLog("bow_worker0.log");
  ASSERT_TRUE(WaitLinked(workers, ns + "/partial_results", {ns + "/placedb_voter"}))
      << ReadLog("bow_voter.log");
  ASSERT_TRUE(WaitLinked({ns + "/placedb_voter"}, ns + "/answers", {ns + "/placedb_feed"}))
      << ReadLog("bow_feed.log");
  const ros::Subscriber gate = OpenGate(ns);
  ASSERT_EQ(WaitExit(feed, kRunLimit), 0) << ReadLog("bow_feed.log");
  const std::vector<nlohmann::json> answers = WaitLines(Path("bow_answers.jsonl"), 44);
  ASSERT_EQ(answers.size(), 44u) << ReadLog("bow_voter.log");
  QueryOptions bow;
  bow.retrieval.method = RetrievalMethod::kBow;
  bow.retrieval.bow_candidates = 8;
  bow.retrieval.guided_candidates = 3;
  const std::vector<QueryResult> expected = ros_testing::SingleProcess(db, kImages, 41, 84, bow);
  for (const nlohmann::json& a : answers) {
    const uint64_t seq = a["frame_seq"];
    ASSERT_LT(seq, 44u);
    EXPECT_TRUE(a["complete"].get<bool>()) << "frame " << seq;
    ExpectSameAnswer(a, expected[seq], "frame " + std::to_string(seq));
  }
  EXPECT_NE(ReadLog("bow_worker0.log").find("two rounds"), std::string::npos);
}

// The voter with --sequence: each answer equals the single-process answers
// fed, in frame order, through a SequenceMatcher over the same keyframes.
TEST_F(RosSystemTest, TheVoterAnswersWithSequenceEvidence) {
  const std::string ns = "/sequence";
  Start({"placedb_voter", "--db", Db(), "--partitions", "2", "--deadline-ms", kNoDeadline,
         "--sequence", "--sequence-length", "5", "--answers-file", Path("sequence_answers.jsonl")},
        "sequence_voter.log", ns);
  for (int i = 0; i < 2; ++i) {
    Start({"placedb_worker", "--db", Db(), "--partition", std::to_string(i) + "/2"},
          "sequence_worker" + std::to_string(i) + ".log", ns);
  }
  // 2 workers + the gate. The feed waits for each answer, so frames are
  // answered in order.
  const pid_t feed = Start({"placedb_feed", "--images", kImages, "--first", "41", "--last", "56",
                            "--wait-for", "2", "--rate", "0", "--answer-timeout-ms", kNoDeadline},
                           "sequence_feed.log", ns);
  const std::vector<std::string> workers = {ns + "/placedb_worker_0", ns + "/placedb_worker_1"};
  ASSERT_TRUE(WaitLinked(workers, ns + "/partial_results", {ns + "/placedb_voter"}))
      << ReadLog("sequence_voter.log");
  ASSERT_TRUE(WaitLinked({ns + "/placedb_voter"}, ns + "/answers", {ns + "/placedb_feed"}))
      << ReadLog("sequence_feed.log");
  const ros::Subscriber gate = OpenGate(ns);
  ASSERT_EQ(WaitExit(feed, kRunLimit), 0) << ReadLog("sequence_feed.log");
  const std::vector<nlohmann::json> answers = WaitLines(Path("sequence_answers.jsonl"), 16);
  ASSERT_EQ(answers.size(), 16u) << ReadLog("sequence_voter.log");
  const std::vector<QueryResult> frames = SingleProcess(QueryOptions());
  SequenceOptions options;
  options.length = 5;
  OpenOptions table;
  table.keyframe_table = true;
  SequenceMatcher matcher(PlaceDatabase::Open(Db(), table).keyframes(), options);
  int by_sequence = 0;
  for (size_t i = 0; i < answers.size(); ++i) {
    const nlohmann::json& a = answers[i];
    ASSERT_EQ(a["frame_seq"].get<uint64_t>(), i);
    const QueryResult expected = matcher.Feed(frames[i]);
    const QueryResult got = QueryResultFromJson(a["result"].dump());
    EXPECT_EQ(got.decided_by, expected.decided_by) << "frame " << i;
    ASSERT_TRUE(got.sequence.has_value());
    EXPECT_EQ(got.sequence->keyframe_id, expected.sequence->keyframe_id) << "frame " << i;
    EXPECT_EQ(got.matched, expected.matched) << "frame " << i;
    EXPECT_EQ(got.ranked.front().keyframe_id, expected.ranked.front().keyframe_id) << "frame " << i;
    by_sequence += got.decided_by == "sequence";
  }
  EXPECT_GE(by_sequence, 14);
  EXPECT_NE(ReadLog("sequence_voter.log").find("sequence evidence"), std::string::npos);
}

// A worker killed (SIGKILL) is answered around and rejoins: the drill of
// ros_testing::RunKillDrill, worker 1 of 3 killed.
TEST_F(RosSystemTest, AKilledWorkerIsAnsweredAroundAndRejoins) {
  const std::string ns = "/faults";
  ros_testing::KillDrill drill;
  drill.ns = ns;
  drill.db = Db();
  drill.images = kImages;
  drill.files = Path("faults_");
  drill.partitions = 3;
  drill.killed = {1};
  drill.start_voter = [&](const std::vector<std::string>& args, const std::string& name) {
    return Start(args, "faults_" + name + ".log", ns);
  };
  drill.start_worker = [&](int i, const std::string& name) {
    return Start({"placedb_worker", "--db", Db(), "--partition", std::to_string(i) + "/3",
                  "__name:=" + name},
                 "faults_" + name + ".log", ns);
  };
  drill.read_log = [](const std::string& name) { return ReadLog("faults_" + name + ".log"); };
  ros_testing::RunKillDrill(drill);
}

// Malformed messages are dropped and logged once per cause; the nodes live
// on and keep answering good frames. Each bad message is sent until its
// node has logged it (then four times more), so none is lost to a queue of
// one while a node is busy, however slow the machine.
TEST_F(RosSystemTest, MalformedMessagesAreDroppedOncePerCause) {
  const std::string ns = "/hostile";
  const pid_t voter = Start({"placedb_voter", "--db", Db(), "--partitions", "1", "--deadline-ms",
                             kNoDeadline, "--answers-file", Path("hostile_answers.jsonl")},
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
  const std::string me = ros::this_node::getName();
  ASSERT_TRUE(WaitLinked({me}, ns + "/image", {ns + "/placedb_worker_0"}));
  ASSERT_TRUE(WaitLinked({me}, ns + "/features", {ns + "/features_worker"}));
  ASSERT_TRUE(WaitLinked({me}, ns + "/partial_results", {ns + "/placedb_voter"}));
  ASSERT_TRUE(WaitLinked({me}, ns + "/frames", {ns + "/placedb_voter"}));
  ASSERT_TRUE(
      WaitLinked({ns + "/placedb_worker_0"}, ns + "/partial_results", {ns + "/placedb_voter"}));
  const cv::Mat good = cv::imread(testing_util::RtabmapImage(42));
  std_msgs::Header h;
  sensor_msgs::Image wrong_encoding = BgrToImageMessage(good, h);
  wrong_encoding.encoding = "16UC1";
  sensor_msgs::Image huge = BgrToImageMessage(good, h);
  huge.width = 100000;
  sensor_msgs::Image short_data = BgrToImageMessage(good, h);
  short_data.data.resize(100);
  placedb_msgs::PartialResult unknown_partition;
  unknown_partition.database_id = PlaceDatabase::Open(Db()).generation();
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
  auto count = [](const std::string& text, const std::string& part) {
    size_t n = 0;
    for (size_t at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++n;
    return n;
  };
  // Sends a bad message until `log` shows its cause, then 4 times more.
  auto until_logged = [&](const std::function<void()>& send, const std::string& log,
                          const std::string& cause) {
    const bool logged = WaitUntil([&] {
      send();
      return WaitUntil([&] { return count(ReadLog(log), cause) > 0; }, 0.25);
    });
    for (int repeat = 0; repeat < 4; ++repeat) {
      send();
      std::this_thread::sleep_for(
          std::chrono::milliseconds(20));  // spaced, not a wait for anything
    }
    return logged;
  };
  EXPECT_TRUE(until_logged([&] { images.publish(wrong_encoding); }, "hostile_worker.log",
                           "(image encoding"));
  EXPECT_TRUE(until_logged([&] { images.publish(huge); }, "hostile_worker.log", "(image size"));
  EXPECT_TRUE(
      until_logged([&] { images.publish(short_data); }, "hostile_worker.log", "(image data"));
  EXPECT_TRUE(until_logged([&] { partials.publish(unknown_partition); }, "hostile_voter.log",
                           "(partition"));
  EXPECT_TRUE(until_logged([&] { partials.publish(other_db); }, "hostile_voter.log", "(database"));
  EXPECT_TRUE(until_logged([&] { features.publish(surf); }, "hostile_features_worker.log",
                           "(the query has surf features"));
  EXPECT_TRUE(until_logged([&] { features.publish(broken); }, "hostile_features_worker.log",
                           "(descriptors"));
  // A good frame after all that is answered. (roscpp numbers each
  // publisher's messages: the bad images went before it, so its number for
  // the worker is not its announcement's; the voter answers it when the
  // worker's partial comes, the only partition.) Sent again every second
  // until answered: a worker still busy with a bad image keeps only the
  // newest.
  bool good_answered = false;
  std::vector<nlohmann::json> answers;
  WaitUntil([&] {
    frames.publish(h);
    images.publish(BgrToImageMessage(good, h));
    return WaitUntil(
        [&] {
          answers = WrittenLines(Path("hostile_answers.jsonl"));
          for (const nlohmann::json& a : answers) {
            const QueryResult r = a["result"].get<QueryResult>();
            // Image 42 shows the place of keyframes 1-4.
            if (r.best() != nullptr && r.best()->keyframe_id >= 1 && r.best()->keyframe_id <= 4)
              good_answered = true;
          }
          return good_answered;
        },
        1.0);
  });
  EXPECT_TRUE(Alive(voter));
  EXPECT_TRUE(Alive(image_worker));
  EXPECT_TRUE(Alive(features_worker));
  ASSERT_FALSE(answers.empty()) << ReadLog("hostile_voter.log");
  EXPECT_TRUE(good_answered) << answers.size() << " answers, first " << answers[0].dump() << "\n"
                             << ReadLog("hostile_worker.log") << ReadLog("hostile_voter.log");
  const std::string worker_log = ReadLog("hostile_worker.log");
  EXPECT_EQ(count(worker_log, "(image encoding"), 1u) << worker_log;
  EXPECT_EQ(count(worker_log, "(image size"), 1u) << worker_log;
  EXPECT_EQ(count(worker_log, "(image data"), 1u) << worker_log;
  const std::string voter_log = ReadLog("hostile_voter.log");
  EXPECT_EQ(count(voter_log, "(database"), 1u) << voter_log;
  EXPECT_EQ(count(voter_log, "(partition"), 1u) << voter_log;
  // Every drop is counted by its cause: on voter_stats (latched) and in the
  // voter's line at shutdown.
  ros::CallbackQueue queue;
  ros::NodeHandle stats_nh;
  stats_nh.setCallbackQueue(&queue);
  nlohmann::json stats;
  const ros::Subscriber stats_sub = stats_nh.subscribe<std_msgs::String>(
      ns + "/voter_stats", 10,
      [&](const std_msgs::StringConstPtr& m) { stats = nlohmann::json::parse(m->data); },
      ros::VoidConstPtr(), ros::TransportHints());
  EXPECT_TRUE(WaitUntil([&] {
    queue.callAvailable();
    return !stats.is_null() && stats["dropped"].value("database", 0) >= 5 &&
           stats["dropped"].value("partition", 0) >= 5 && stats["answered"].get<int>() >= 1;
  })) << stats.dump();
  LoopbackRos::Stop(voter);
  const std::string at_shutdown = ReadLog("hostile_voter.log");
  EXPECT_NE(at_shutdown.find("(at shutdown)"), std::string::npos) << at_shutdown;
  const size_t line = at_shutdown.rfind("dropped: ");
  ASSERT_NE(line, std::string::npos) << at_shutdown;
  EXPECT_NE(
      at_shutdown.find("database " + std::to_string(stats["dropped"]["database"].get<int>()), line),
      std::string::npos)
      << at_shutdown;
  EXPECT_NE(at_shutdown.find("partition ", line), std::string::npos) << at_shutdown;
  const std::string features_log = ReadLog("hostile_features_worker.log");
  EXPECT_EQ(count(features_log, "(the query has surf features"), 1u) << features_log;
  EXPECT_EQ(count(features_log, "(descriptors"), 1u) << features_log;
}

// roslaunch with the shipped launch file: a voter, an extractor, two workers
// and a feed on one machine, found as the ROS package "placedb" in the build
// tree. With input:=features only the extractor reads the image topic, so the
// feed's --wait-for 2 (one per worker, from the launch file) counts the
// extractor and this process's gate: the feed starts once every link is up.
TEST_F(RosSystemTest, TheLaunchFileRunsTheSystem) {
  const std::string tree = PLACEDB_ROS_TREE;
  ::setenv("ROS_PACKAGE_PATH", (tree + "/share").c_str(), 1);
  const char* prefix = std::getenv("CMAKE_PREFIX_PATH");
  ::setenv("CMAKE_PREFIX_PATH", (tree + (prefix ? std::string(":") + prefix : "")).c_str(), 1);
  const std::string ns = "/launched";
  const pid_t launch =
      Start({"roslaunch", "placedb", "placedb.launch", "db:=" + Db(), "workers:=2",
             "input:=features", "deadline_ms:=" + kNoDeadline, "images:=" + kImages,
             "answers_file:=" + Path("launch_answers.jsonl"), "feed_required:=true",
             "feed_args:=--rate 0 --first 70 --answer-timeout-ms " + kNoDeadline},
            "launch.log", ns);
  const std::vector<std::string> workers = {ns + "/placedb_worker_0", ns + "/placedb_worker_1"};
  ASSERT_TRUE(WaitLinked({ns + "/placedb_extractor"}, ns + "/features", workers))
      << ReadLog("launch.log");
  ASSERT_TRUE(WaitLinked(workers, ns + "/partial_results", {ns + "/placedb_voter"}))
      << ReadLog("launch.log");
  ASSERT_TRUE(WaitLinked({ns + "/placedb_voter"}, ns + "/answers", {ns + "/placedb_feed"}))
      << ReadLog("launch.log");
  const ros::Subscriber gate = OpenGate(ns);
  // feed_required:=true: when the feed has published its frames, roslaunch ends.
  EXPECT_EQ(WaitExit(launch, kRunLimit), 0) << ReadLog("launch.log");
  const std::vector<nlohmann::json> answers = WaitLines(Path("launch_answers.jsonl"), 15);
  ASSERT_EQ(answers.size(), 15u) << ReadLog("launch.log");
  const std::vector<QueryResult> expected = SingleProcess(QueryOptions());
  for (const nlohmann::json& a : answers) {
    EXPECT_TRUE(a["complete"].get<bool>());
    ExpectSameAnswer(a, expected[29 + a["frame_seq"].get<uint64_t>()], "launched frame");
  }
}

// Points roslaunch at the build tree's package placedb.
void UseTheBuildTree() {
  const std::string tree = PLACEDB_ROS_TREE;
  ::setenv("ROS_PACKAGE_PATH", (tree + "/share").c_str(), 1);
  const char* prefix = std::getenv("CMAKE_PREFIX_PATH");
  if (prefix == nullptr || std::string(prefix).find(tree) == std::string::npos)
    ::setenv("CMAKE_PREFIX_PATH", (tree + (prefix ? std::string(":") + prefix : "")).c_str(), 1);
}

// feed_required defaults to false: when the feed has published its frames
// (and exited), the voter and the workers stay up for more feeds. (And
// voter_args reaches the voter: --sequence.)
TEST_F(RosSystemTest, TheLaunchStaysUpAfterTheFeedByDefault) {
  UseTheBuildTree();
  const std::string ns = "/launched_stays";
  const pid_t launch =
      Start({"roslaunch", "placedb", "placedb.launch", "db:=" + Db(), "workers:=2",
             "deadline_ms:=" + kNoDeadline, "images:=" + kImages,
             "answers_file:=" + Path("stays_answers.jsonl"), "voter_args:=--sequence",
             "feed_args:=--rate 0 --first 80 --answer-timeout-ms " + kNoDeadline},
            "launch_stays.log", ns);
  const std::vector<std::string> workers = {ns + "/placedb_worker_0", ns + "/placedb_worker_1"};
  ASSERT_TRUE(WaitLinked(workers, ns + "/partial_results", {ns + "/placedb_voter"}))
      << ReadLog("launch_stays.log");
  ASSERT_TRUE(WaitLinked({ns + "/placedb_voter"}, ns + "/answers", {ns + "/placedb_feed"}))
      << ReadLog("launch_stays.log");
  const ros::Subscriber gate = OpenGate(ns);
  const std::vector<nlohmann::json> answers = WaitLines(Path("stays_answers.jsonl"), 5);
  ASSERT_EQ(answers.size(), 5u) << ReadLog("launch_stays.log");
  // voter_args:=--sequence reached the voter: from the second frame on, the
  // sequence answers.
  for (size_t i = 1; i < answers.size(); ++i)
    EXPECT_EQ(answers[i]["result"]["decided_by"], "sequence") << "frame " << i;
  // roslaunch reports the feed's end; then the launch is still up.
  ASSERT_TRUE(WaitUntil([&] {
    // "[launched_stays/placedb_feed-5] process has finished cleanly"
    const std::string log = ReadLog("launch_stays.log");
    const size_t feed = log.find("/placedb_feed-");
    return feed != std::string::npos &&
           log.find("] process has finished cleanly", feed) != std::string::npos;
  })) << ReadLog("launch_stays.log");
  EXPECT_EQ(LoopbackRos::WaitExit(launch, 0.5), -1) << ReadLog("launch_stays.log");
  EXPECT_TRUE(Alive(launch));
  EXPECT_TRUE(Linked(ns + "/placedb_worker_0", ns + "/partial_results", ns + "/placedb_voter"));
  LoopbackRos::Stop(launch);
}

// A database that does not exist: each node says so in one line and exits 1;
// the voter is required, so roslaunch ends the launch (and says why) instead
// of idling with nothing running.
TEST_F(RosSystemTest, ALaunchWithoutADatabaseEnds) {
  UseTheBuildTree();
  const std::string ns = "/launched_nodb";
  const pid_t launch =
      Start({"roslaunch", "placedb", "placedb.launch", "db:=" + Path("no_such_db"), "workers:=2"},
            "launch_nodb.log", ns);
  EXPECT_NE(WaitExit(launch, kLimit), -1) << ReadLog("launch_nodb.log");
  const std::string log = ReadLog("launch_nodb.log");
  EXPECT_NE(log.find("placedb_voter: error: no database at " + Path("no_such_db")),
            std::string::npos)
      << log;
  EXPECT_NE(log.find("REQUIRED process ["), std::string::npos) << log;
  // Run alone, a node says it in one line and exits 1.
  for (const std::string node : {"placedb_voter", "placedb_worker", "placedb_extractor"}) {
    const std::string out = Path(node + "_nodb.log");
    const std::string cmd = kNodes + node + " --db " + Path("no_such_db") +
                            (node == "placedb_voter" ? " --partitions 2" : "") +
                            (node == "placedb_worker" ? " --partition 0/2" : "") + " > " + out +
                            " 2>&1";
    const int status = std::system(cmd.c_str());
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1) << node << " " << status;
    EXPECT_EQ(ReadLog(node + "_nodb.log"),
              node + ": error: no database at " + Path("no_such_db") + " (no such directory)\n");
  }
}

// Each node's help names it and ends with examples; a bad flag is one line
// that names it.
TEST_F(RosSystemTest, NodeHelpNamesTheNode) {
  for (const std::string node :
       {"placedb_feed", "placedb_worker", "placedb_voter", "placedb_extractor"}) {
    const std::string out = Path(node + "_help.log");
    ASSERT_EQ(std::system((kNodes + node + " --help > " + out + " 2>&1").c_str()), 0) << node;
    const std::string help = ReadLog(node + "_help.log");
    EXPECT_EQ(help.rfind(node + ": ", 0), 0u) << help;
    EXPECT_NE(help.find("\nUsage: " + node + " [OPTIONS]\n"), std::string::npos) << help;
    const size_t examples = help.rfind("\nExamples:\n");
    ASSERT_NE(examples, std::string::npos) << help;
    // Only example lines after it, two or three, each a command.
    std::vector<std::string> lines;
    for (size_t at = examples + 11, end; (end = help.find('\n', at)) != std::string::npos;
         at = end + 1) {
      if (end > at) lines.push_back(help.substr(at, end - at));
    }
    ASSERT_GE(lines.size(), 2u) << help;
    ASSERT_LE(lines.size(), 3u) << help;
    for (const std::string& line : lines) {
      EXPECT_TRUE(line.rfind("  " + node + " ", 0) == 0 ||
                  line.rfind("  roslaunch placedb ", 0) == 0)
          << line;
    }
    const int status = std::system((kNodes + node + " --no-such-flag > " + out + " 2>&1").c_str());
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1) << node;
    const std::string error = ReadLog(node + "_help.log");
    EXPECT_EQ(error.rfind(node + ": error: ", 0), 0u) << error;
    EXPECT_EQ(std::count(error.begin(), error.end(), '\n'), 1) << error;
  }
}

// The last line of a feed's --log-file: its run's report.
nlohmann::json FeedReport(const std::string& path) {
  const std::vector<nlohmann::json> lines = LoopbackRos::ReadJsonLines(path);
  if (lines.empty() || !lines.back().contains("frames_sent")) return nlohmann::json();
  return lines.back();
}

// Finding 4 of issue #19: a second feed into a running voter was answered
// with silence (its numbers, from 0 again, were "late"). Each feed run has a
// run id; a new one resets the voter, and so does the same run's numbering
// going back (a bag of the feed played again keeps its run id and numbers).
// Every frame of each of the three runs is answered once, under its run.
TEST_F(RosSystemTest, ASecondFeedRunIsAnswered) {
  const std::string ns = "/second";
  const std::string answers_file = Path("second_answers.jsonl");
  // A deadline in reach: a worker's result for frame 0 of a new run that
  // comes before the run's announcement is refused as late (it cannot be
  // told from the previous run's), and that frame is answered without it.
  const pid_t voter = Start({"placedb_voter", "--db", Db(), "--partitions", "2", "--deadline-ms",
                             "3000", "--answers-file", answers_file, "--stats-period", "0.5"},
                            "second_voter.log", ns);
  for (int i = 0; i < 2; ++i) {
    Start({"placedb_worker", "--db", Db(), "--partition", std::to_string(i) + "/2"},
          "second_worker" + std::to_string(i) + ".log", ns);
  }
  const std::vector<std::string> workers = {ns + "/placedb_worker_0", ns + "/placedb_worker_1"};
  ASSERT_TRUE(WaitLinked(workers, ns + "/partial_results", {ns + "/placedb_voter"}))
      << ReadLog("second_voter.log");
  ros::CallbackQueue queue;
  ros::NodeHandle nh;
  nh.setCallbackQueue(&queue);
  nlohmann::json stats;
  const ros::Subscriber stats_sub = nh.subscribe<std_msgs::String>(
      ns + "/voter_stats", 10,
      [&](const std_msgs::StringConstPtr& m) { stats = nlohmann::json::parse(m->data); },
      ros::VoidConstPtr(), ros::TransportHints());
  const ros::Subscriber gate = OpenGate(ns);
  // Three runs of frames 41..56: two feeds, then the second's run id again.
  std::vector<std::string> runs;
  for (int run = 0; run < 3; ++run) {
    const std::string name = "placedb_feed_" + std::to_string(run);
    std::vector<std::string> args = {"placedb_feed",
                                     "--images",
                                     kImages,
                                     "--first",
                                     "41",
                                     "--last",
                                     "56",
                                     "--wait-for",
                                     "3",
                                     "--rate",
                                     "0",
                                     "--answer-timeout-ms",
                                     kNoDeadline,
                                     "--log-file",
                                     Path(name + ".jsonl"),
                                     "__name:=" + name};
    if (run == 2) {
      args.push_back("--run-id");
      args.push_back(runs[1]);
    }
    const pid_t feed = Start(args, name + ".log", ns);
    ASSERT_EQ(WaitExit(feed, kRunLimit), 0)
        << ReadLog(name + ".log") << ReadLog("second_voter.log");
    const nlohmann::json report = FeedReport(Path(name + ".jsonl"));
    ASSERT_FALSE(report.is_null()) << ReadLog(name + ".log");
    EXPECT_EQ(report["frames_sent"], 16) << report.dump();
    EXPECT_EQ(report["answered"], 16) << report.dump() << ReadLog("second_voter.log");
    EXPECT_EQ(report["never_answered"], 0) << report.dump();
    EXPECT_EQ(report["complete"].get<int>() + report["partial"].get<int>(), 16) << report.dump();
    EXPECT_NE(ReadLog(name + ".log").find("16 frames sent, 16 answered"), std::string::npos)
        << ReadLog(name + ".log");
    runs.push_back(report["run"]);
  }
  EXPECT_NE(runs[0], runs[1]);
  EXPECT_EQ(runs[1], runs[2]);
  // The answers file: each run's 16 frames once (runs 1 and 2 share an id).
  std::map<std::string, std::multiset<uint64_t>> frames;
  for (const nlohmann::json& a : WaitLines(answers_file, 48))
    frames[a["run"].get<std::string>()].insert(a["frame_seq"].get<uint64_t>());
  ASSERT_EQ(frames[runs[0]].size(), 16u) << ReadLog("second_voter.log");
  ASSERT_EQ(frames[runs[1]].size(), 32u) << ReadLog("second_voter.log");
  for (uint64_t f = 0; f < 16; ++f) {
    EXPECT_EQ(frames[runs[0]].count(f), 1u) << f;
    EXPECT_EQ(frames[runs[1]].count(f), 2u) << f;
  }
  // voter_stats: 48 answers in 3 runs.
  EXPECT_TRUE(WaitUntil([&] {
    queue.callAvailable();
    return !stats.is_null() && stats["answered"] == 48 && stats["runs"] == 3;
  })) << stats.dump();
  // The periodic report (every 0.5 s, when the counts changed) has them too.
  EXPECT_TRUE(WaitUntil([&] {
    return ReadLog("second_voter.log").find("]: placedb_voter: 48 frames answered (") !=
           std::string::npos;
  })) << ReadLog("second_voter.log");
  // Stopped by SIGTERM, the voter reports once more.
  LoopbackRos::Stop(voter);
  const std::string log = ReadLog("second_voter.log");
  EXPECT_NE(log.find("\nplacedb_voter: 48 frames answered ("), std::string::npos) << log;
  EXPECT_NE(log.find("in 3 feed runs; dropped: "), std::string::npos) << log;
  EXPECT_NE(log.find("(at shutdown)"), std::string::npos) << log;
}

// A bag of a feed's topics (frames, image) played twice with rosbag play at
// its own pace (10 Hz) into a running voter: the second play keeps the run
// id and numbers 0..7 again, which starts a new run; every frame of both
// plays is answered once. (rosbag play -k stays up after the bag, so no
// message is lost to its exit; this test stops it.)
TEST_F(RosSystemTest, ABagPlayedTwiceIsAnsweredTwice) {
  const std::string ns = "/bagplay";
  const std::string answers_file = Path("bagplay_answers.jsonl");
  const std::string bag_path = Path("feed.bag");
  {
    rosbag::Bag bag(bag_path, rosbag::bagmode::Write);
    const std::vector<Frame> frames = ListImageFolder(kImages, 41, 48);
    for (size_t i = 0; i < frames.size(); ++i) {
      std_msgs::Header h;
      h.seq = static_cast<uint32_t>(i);
      h.stamp = ros::Time(200.0 + 0.1 * static_cast<double>(i));
      h.frame_id = "0123456789abcdef";  // the recorded feed's run id
      bag.write(ns + "/frames", h.stamp, h);
      h.frame_id = "camera";
      bag.write(ns + "/image", h.stamp, BgrToImageMessage(LoadFrameImage(frames[i]), h));
    }
  }
  const pid_t voter = Start({"placedb_voter", "--db", Db(), "--partitions", "2", "--deadline-ms",
                             "2000", "--answers-file", answers_file},
                            "bagplay_voter.log", ns);
  for (int i = 0; i < 2; ++i) {
    Start({"placedb_worker", "--db", Db(), "--partition", std::to_string(i) + "/2"},
          "bagplay_worker" + std::to_string(i) + ".log", ns);
  }
  ASSERT_TRUE(WaitLinked({ns + "/placedb_worker_0", ns + "/placedb_worker_1"},
                         ns + "/partial_results", {ns + "/placedb_voter"}))
      << ReadLog("bagplay_voter.log");
  for (size_t play = 1; play <= 2; ++play) {
    const pid_t player = Start({"rosbag", "play", "--quiet", "--keep-alive",
                                "--wait-for-subscribers", bag_path, "__name:=player"},
                               "bagplay_player.log", "");
    EXPECT_EQ(WaitLines(answers_file, 8 * play).size(), 8 * play)
        << ReadLog("bagplay_voter.log") << ReadLog("bagplay_player.log");
    LoopbackRos::Stop(player);
  }
  std::map<uint64_t, int> answered;
  for (const nlohmann::json& a : WrittenLines(answers_file)) {
    EXPECT_EQ(a["run"], "0123456789abcdef");
    ++answered[a["frame_seq"].get<uint64_t>()];
  }
  ASSERT_EQ(answered.size(), 8u) << ReadLog("bagplay_voter.log");
  for (const auto& [seq, n] : answered) EXPECT_EQ(n, 2) << "frame " << seq;
  LoopbackRos::Stop(voter);
  EXPECT_NE(ReadLog("bagplay_voter.log").find("16 frames answered"), std::string::npos)
      << ReadLog("bagplay_voter.log");
  EXPECT_NE(ReadLog("bagplay_voter.log").find("in 2 feed runs"), std::string::npos)
      << ReadLog("bagplay_voter.log");
}

// Finding 4 of issue #19: nothing reported frames fed but never answered.
// The feed's report counts them, and its complete / partial counts are the
// voter's: worker 1 killed before the feed, every answer is partial; with no
// voter at all, no frame is answered.
TEST_F(RosSystemTest, TheFeedReportsFramesNeverAnswered) {
  const std::string ns = "/report";
  Start({"placedb_voter", "--db", Db(), "--partitions", "2", "--deadline-ms", "300",
         "--answers-file", Path("report_answers.jsonl")},
        "report_voter.log", ns);
  Start({"placedb_worker", "--db", Db(), "--partition", "0/2"}, "report_worker0.log", ns);
  const pid_t worker1 =
      Start({"placedb_worker", "--db", Db(), "--partition", "1/2"}, "report_worker1.log", ns);
  ASSERT_TRUE(WaitLinked({ns + "/placedb_worker_0", ns + "/placedb_worker_1"},
                         ns + "/partial_results", {ns + "/placedb_voter"}))
      << ReadLog("report_voter.log");
  ASSERT_EQ(::kill(worker1, SIGKILL), 0);
  ASSERT_EQ(WaitExit(worker1, kLimit), 128);
  {
    const ros::Subscriber gate = OpenGate(ns);
    // Worker 0 + the gate.
    const pid_t feed = Start({"placedb_feed", "--images", kImages, "--first", "41", "--last", "48",
                              "--wait-for", "2", "--rate", "0", "--answer-timeout-ms", kNoDeadline,
                              "--log-file", Path("report_feed.jsonl")},
                             "report_feed.log", ns);
    ASSERT_EQ(WaitExit(feed, kRunLimit), 0) << ReadLog("report_feed.log");
  }
  const nlohmann::json report = FeedReport(Path("report_feed.jsonl"));
  ASSERT_FALSE(report.is_null()) << ReadLog("report_feed.log");
  EXPECT_EQ(report["frames_sent"], 8);
  EXPECT_EQ(report["answered"], 8);
  EXPECT_EQ(report["complete"], 0);
  EXPECT_EQ(report["partial"], 8);
  EXPECT_EQ(report["never_answered"], 0);
  EXPECT_NE(ReadLog("report_feed.log")
                .find("8 frames sent, 8 answered (0 complete, 8 partial), 0 never answered"),
            std::string::npos)
      << ReadLog("report_feed.log");
  size_t partial = 0;
  for (const nlohmann::json& a : WaitLines(Path("report_answers.jsonl"), 8)) {
    if (a["run"] == report["run"] && !a["complete"].get<bool>() &&
        a["missing"] == nlohmann::json{1})
      ++partial;
  }
  EXPECT_EQ(partial, 8u);

  // No voter: this process takes the announcements and never answers.
  const std::string quiet = "/report_quiet";
  ros::NodeHandle nh;
  const ros::Subscriber frames = nh.subscribe<std_msgs::Header>(
      quiet + "/frames", 10, [](const std_msgs::HeaderConstPtr&) {}, ros::VoidConstPtr(),
      ros::TransportHints());
  const ros::Subscriber gate = OpenGate(quiet);
  const pid_t feed = Start(
      {"placedb_feed", "--images", kImages, "--first", "41", "--last", "45", "--wait-for", "1",
       "--rate", "0", "--answer-timeout-ms", "100", "--log-file", Path("quiet_feed.jsonl")},
      "quiet_feed.log", quiet);
  ASSERT_EQ(WaitExit(feed, kRunLimit), 0) << ReadLog("quiet_feed.log");
  const nlohmann::json none = FeedReport(Path("quiet_feed.jsonl"));
  ASSERT_FALSE(none.is_null()) << ReadLog("quiet_feed.log");
  EXPECT_EQ(none["frames_sent"], 5);
  EXPECT_EQ(none["answered"], 0);
  EXPECT_EQ(none["never_answered"], 5);
  EXPECT_EQ(none["never_answered_frames"], (nlohmann::json{0, 1, 2, 3, 4}));
  EXPECT_NE(ReadLog("quiet_feed.log")
                .find("5 frames sent, 0 answered (0 complete, 0 partial), 5 never answered "
                      "(frames 0 1 2 3 4)"),
            std::string::npos)
      << ReadLog("quiet_feed.log");
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
