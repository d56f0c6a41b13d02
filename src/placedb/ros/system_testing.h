// What the ROS system tests share (test support, not installed): waiting for
// events with a limit that only ends a hang, a node's links as the
// publishing node reports them, answers files, the single-process answers a
// complete answer must equal, and the drill in which workers are killed and
// restarted. Nothing here asserts a clock.
#pragma once

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sys/types.h>

#include <functional>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "placedb/query/query.h"

namespace placedb {
namespace ros_testing {

// Seconds: the limit of every wait for an event (a node up and linked, an
// answer written). Generous: it only ends a hang.
constexpr double kLimit = 300;
// Seconds for a feed to publish all its frames, each answered.
constexpr double kRunLimit = 600;
// Milliseconds: a voter deadline (and a feed's answer timeout) no answer
// reaches: the voter answers when every partition has, however slow.
inline const std::string kNoDeadline = "600000";

// Waits until done() is true, polling; false when `seconds` pass first.
bool WaitUntil(const std::function<bool()>& done, double seconds = kLimit);

// The XML-RPC URI node `name` registered with the master ("" when unknown).
std::string NodeUri(const std::string& name);

// Whether node `publisher` (a full name, or this process) has a live link
// on `topic` to node `subscriber`, as the publisher reports it (its
// getBusInfo): what it publishes from then on reaches the subscriber. A
// subscriber's own view is not enough: it lists a link before the publisher
// has accepted it.
bool Linked(const std::string& publisher, const std::string& topic, const std::string& subscriber);

// Waits (kLimit) until every publisher -> subscriber link on `topic` is up.
::testing::AssertionResult WaitLinked(const std::vector<std::string>& publishers,
                                      const std::string& topic,
                                      const std::vector<std::string>& subscribers);

// The lines a node has finished writing to a JSON-lines file (not one it is
// still writing).
std::vector<nlohmann::json> WrittenLines(const std::string& path);
// Waits (kLimit) until the JSON-lines file holds at least `count` lines;
// returns them.
std::vector<nlohmann::json> WaitLines(const std::string& path, size_t count);

// The gate: this process subscribes to `ns`/image, the last subscriber a
// feed started with --wait-for (the system's subscribers + 1) waits for.
ros::Subscriber OpenGate(const std::string& ns);

// What the single-process query of database `db` answers for images
// first..last of the folder `images`.
std::vector<QueryResult> SingleProcess(const std::string& db, const std::string& images, int first,
                                       int last, const QueryOptions& options = QueryOptions());

// An answer line (--answers-file) has the ranking of `expected`.
void ExpectSameAnswer(const nlohmann::json& line, const QueryResult& expected,
                      const std::string& what);

// Whether the JSON list `list` (an answer's answered or missing) holds
// `partition`.
bool HasPartition(const nlohmann::json& list, int partition);

// Workers killed (SIGKILL) do not stop the system: frames are answered
// without them, flagged partial and naming their partitions; restarted,
// they rejoin and answers are complete again. This process plays the feed
// (one frame at a time, each the next once it is answered), and two voters
// watch the same frames:
// - the patient one (no deadline in reach, --max-pending 1) answers a frame
//   when every partition has, or when the next frame comes;
// - the deadline one (--deadline-ms 300) answers each frame at its deadline
//   at the latest: the path a real system takes when a worker is gone.
// Nothing depends on how fast anything runs: with every worker linked, a
// frame's patient answer is complete (it waits for all); with the killed
// workers reaped no partial of their partitions can exist, so every answer
// of that phase, from either voter, names them missing; the deadline voter,
// which neither evicts nor completes those frames, answered them by the
// deadline (waited at least 300 ms by its own clock).
struct KillDrill {
  std::string ns;  // the nodes' ROS namespace
  std::string db, images;
  std::string files;  // the answers files' path prefix ("<dir>/faults_")
  int partitions = 3;
  std::set<int> killed;  // the partitions whose workers are killed
  // Starts a voter (args, log) and partition i's worker under node name
  // `name` (its log named after it); each returns the PID.
  std::function<pid_t(const std::vector<std::string>&, const std::string&)> start_voter;
  std::function<pid_t(int i, const std::string& name)> start_worker;
  // A node's log by name (its file), for failure messages.
  std::function<std::string(const std::string&)> read_log;
};
// Runs the drill (images 41..57 of `images`); fails the test where it fails.
void RunKillDrill(const KillDrill& drill);

}  // namespace ros_testing
}  // namespace placedb
