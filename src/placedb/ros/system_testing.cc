#include "placedb/ros/system_testing.h"

#include <placedb_msgs/PartialResult.h>
#include <ros/network.h>
#include <sensor_msgs/Image.h>
#include <signal.h>
#include <std_msgs/Header.h>
#include <xmlrpcpp/XmlRpcClient.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <thread>

#include "placedb/dataset/bag/image_message.h"
#include "placedb/dataset/image_folder.h"
#include "placedb/ros/testbed.h"
#include "placedb/session/place_database.h"

namespace placedb {
namespace ros_testing {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::string FileText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

}  // namespace

bool WaitUntil(const std::function<bool()>& done, double seconds) {
  const auto until = Clock::now() + std::chrono::duration<double>(seconds);
  while (!done()) {
    if (Clock::now() >= until) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

std::string NodeUri(const std::string& name) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = name;
  if (!ros::master::execute("lookupNode", args, result, payload, false)) return "";
  return std::string(payload);
}

bool Linked(const std::string& publisher, const std::string& topic, const std::string& subscriber) {
  std::string host;
  uint32_t port = 0;
  if (!ros::network::splitURI(NodeUri(publisher), host, port)) return false;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  XmlRpc::XmlRpcValue call, info;
  call[0] = ros::this_node::getName();
  const bool answered = client.execute("getBusInfo", call, info);
  client.close();
  if (!answered || info.getType() != XmlRpc::XmlRpcValue::TypeArray || info.size() < 3 ||
      info[2].getType() != XmlRpc::XmlRpcValue::TypeArray)
    return false;
  // Each link: [id, the other node, "o" (we publish) or "i", transport, topic, ...].
  for (int i = 0; i < info[2].size(); ++i) {
    XmlRpc::XmlRpcValue& link = info[2][i];
    if (link.getType() == XmlRpc::XmlRpcValue::TypeArray && link.size() >= 5 &&
        std::string(link[1]) == subscriber && std::string(link[2]) == "o" &&
        std::string(link[4]) == topic)
      return true;
  }
  return false;
}

::testing::AssertionResult WaitLinked(const std::vector<std::string>& publishers,
                                      const std::string& topic,
                                      const std::vector<std::string>& subscribers) {
  for (const std::string& p : publishers) {
    for (const std::string& s : subscribers) {
      if (!WaitUntil([&] { return Linked(p, topic, s); }))
        return ::testing::AssertionFailure()
               << p << " has no link to " << s << " on " << topic << " after " << kLimit << " s";
    }
  }
  return ::testing::AssertionSuccess();
}

std::vector<nlohmann::json> WrittenLines(const std::string& path) {
  const std::string text = FileText(path);
  std::vector<nlohmann::json> out;
  for (size_t at = 0, end; (end = text.find('\n', at)) != std::string::npos; at = end + 1) {
    if (end > at) out.push_back(nlohmann::json::parse(text.substr(at, end - at)));
  }
  return out;
}

std::vector<nlohmann::json> WaitLines(const std::string& path, size_t count) {
  std::vector<nlohmann::json> lines;
  WaitUntil([&] {
    lines = WrittenLines(path);
    return lines.size() >= count;
  });
  return lines;
}

ros::Subscriber OpenGate(const std::string& ns) {
  ros::NodeHandle nh;
  return nh.subscribe<sensor_msgs::Image>(
      ns + "/image", 1, [](const sensor_msgs::ImageConstPtr&) {}, ros::VoidConstPtr(),
      ros::TransportHints());
}

std::vector<QueryResult> SingleProcess(const std::string& db, const std::string& images, int first,
                                       int last, const QueryOptions& options) {
  const PlaceDatabase database = PlaceDatabase::Open(db);
  std::vector<QueryResult> out;
  for (const Frame& f : ListImageFolder(images, first, last))
    out.push_back(database.Query(LoadFrameImage(f), options));
  return out;
}

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

bool HasPartition(const nlohmann::json& list, int partition) {
  for (const nlohmann::json& p : list) {
    if (p.get<int>() == partition) return true;
  }
  return false;
}

void RunKillDrill(const KillDrill& d) {
  const std::string& ns = d.ns;
  const std::string patient_file = d.files + "patient.jsonl";
  const std::string deadline_file = d.files + "deadline.jsonl";
  const double deadline_ms = 300;
  const std::string n = std::to_string(d.partitions);
  const std::string voter = ns + "/placedb_voter", deadline_voter = ns + "/placedb_voter_deadline";
  d.start_voter({"placedb_voter", "--db", d.db, "--partitions", n, "--deadline-ms", kNoDeadline,
                 "--max-pending", "1", "--answers-file", patient_file},
                "placedb_voter");
  d.start_voter({"placedb_voter", "--db", d.db, "--partitions", n, "--deadline-ms", "300",
                 "--answers-file", deadline_file, "__name:=placedb_voter_deadline",
                 "answers:=answers_deadline", "pose:=pose_deadline"},
                "placedb_voter_deadline");
  std::vector<pid_t> workers;
  std::vector<std::string> names;
  for (int i = 0; i < d.partitions; ++i) {
    names.push_back(ns + "/placedb_worker_" + std::to_string(i));
    workers.push_back(d.start_worker(i, "placedb_worker_" + std::to_string(i)));
  }
  ros::NodeHandle nh(ns);
  ros::Publisher frames = nh.advertise<std_msgs::Header>("frames", 100);
  ros::Publisher images = nh.advertise<sensor_msgs::Image>("image", 100);
  const std::string me = ros::this_node::getName();
  // Every link a frame travels: this process -> voters (frames) and workers
  // (image), workers -> voters (partial results).
  auto linked = [&](const std::vector<std::string>& names) {
    return WaitLinked({me}, ns + "/frames", {voter, deadline_voter}) &&
           WaitLinked({me}, ns + "/image", names) &&
           WaitLinked(names, ns + "/partial_results", {voter, deadline_voter});
  };
  auto logs = [&] {
    return d.read_log("placedb_voter") + d.read_log("placedb_voter_deadline") +
           FileText(patient_file) + FileText(deadline_file);
  };
  ASSERT_TRUE(linked(names)) << logs();

  // One frame: its announcement, then its image, both numbered from 0 (the
  // image by roscpp, which numbers a message's header per publisher; the
  // announcement, a bare Header that roscpp leaves alone, here).
  const std::vector<Frame> list = ListImageFolder(d.images, 41, 84);
  std::vector<size_t> frame_of;  // list index by frame_seq
  std::set<uint64_t> without;    // frames sent while the killed workers were dead
  auto send = [&](size_t index) {
    std_msgs::Header h;
    h.seq = static_cast<uint32_t>(frame_of.size());
    h.stamp = ros::Time(1000.0 + static_cast<double>(frame_of.size()));
    frames.publish(h);
    images.publish(BgrToImageMessage(LoadFrameImage(list[index]), h));
    frame_of.push_back(index);
  };
  auto lines = [&](const std::string& file, size_t n) { return WaitLines(file, n).size(); };

  // Every worker: each frame waits for both voters' answers.
  for (size_t i = 0; i < 6; ++i) {
    send(i);
    ASSERT_EQ(lines(patient_file, frame_of.size()), frame_of.size()) << logs();
    ASSERT_EQ(lines(deadline_file, frame_of.size()), frame_of.size()) << logs();
  }
  // Killed and reaped: their partitions can no longer answer anything.
  for (const int k : d.killed) ASSERT_EQ(::kill(workers[k], SIGKILL), 0);
  for (const int k : d.killed) ASSERT_EQ(LoopbackRos::WaitExit(workers[k], kLimit), 128);
  for (size_t i = 6; i < 11; ++i) {
    without.insert(frame_of.size());
    send(i);
    // The deadline voter answers it by its deadline; the patient one answers
    // the previous frame now that this one came.
    ASSERT_EQ(lines(deadline_file, frame_of.size()), frame_of.size()) << logs();
    ASSERT_EQ(lines(patient_file, frame_of.size() - 1), frame_of.size() - 1) << logs();
  }
  // Restarted (under new node names, so that their links cannot be mistaken
  // for the dead ones') and linked: they rejoin.
  std::vector<std::string> again;
  for (const int k : d.killed) {
    const std::string name = "placedb_worker_" + std::to_string(k) + "_again";
    d.start_worker(k, name);
    again.push_back(ns + "/" + name);
  }
  ASSERT_TRUE(linked(again)) << logs();
  for (size_t i = 11; i < 17; ++i) {
    send(i);
    ASSERT_EQ(lines(patient_file, frame_of.size()), frame_of.size()) << logs();
    ASSERT_EQ(lines(deadline_file, frame_of.size()), frame_of.size()) << logs();
  }

  const std::vector<QueryResult> expected = SingleProcess(d.db, d.images, 41, 84);
  for (const std::string& file : {patient_file, deadline_file}) {
    SCOPED_TRACE(file);
    const std::vector<nlohmann::json> answers = WrittenLines(file);
    ASSERT_EQ(answers.size(), frame_of.size()) << "every frame is answered once";
    std::set<uint64_t> seqs;
    size_t partial = 0;
    double least_wait = 1e300, most_wait = 0;
    for (const nlohmann::json& a : answers) {
      const uint64_t seq = a["frame_seq"];
      ASSERT_LT(seq, frame_of.size());
      EXPECT_TRUE(seqs.insert(seq).second) << "answered twice: " << seq;
      const bool complete = a["complete"].get<bool>();
      if (!complete) {
        ++partial;
        least_wait = std::min(least_wait, a["wait_ms"].get<double>());
        most_wait = std::max(most_wait, a["wait_ms"].get<double>());
      }
      if (without.count(seq)) {
        EXPECT_FALSE(complete) << a.dump();
        for (const int k : d.killed) {
          EXPECT_TRUE(HasPartition(a["missing"], k)) << a.dump();
          EXPECT_FALSE(HasPartition(a["answered"], k)) << a.dump();
        }
        // Neither complete nor evicted: answered by the deadline.
        if (file == deadline_file) {
          EXPECT_GE(a["wait_ms"].get<double>(), deadline_ms) << a.dump();
        }
      } else if (file == patient_file) {
        EXPECT_TRUE(complete) << a.dump();  // with every worker before the kill, or restarted
      }
      // A complete answer, from either voter, is the single-process query's.
      if (complete) ExpectSameAnswer(a, expected[frame_of[seq]], "frame " + std::to_string(seq));
    }
    std::cout << "[   drill  ] " << fs::path(file).filename().string() << ": " << answers.size()
              << " answers, " << partial << " partial (" << without.size()
              << " sent without the killed workers)";
    if (partial > 0) std::cout << ", partial ones waited " << least_wait << " to " << most_wait << " ms";
    std::cout << "\n";
  }
}

}  // namespace ros_testing
}  // namespace placedb
