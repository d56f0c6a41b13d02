// What the ROS nodes share: command lines (placedb's flag groups), pinning to
// a CPU, logging a bad message once per cause, wall-clock milliseconds.
#pragma once

#include <ros/ros.h>

#include <CLI/CLI.hpp>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace placedb {
namespace ros_node {

// The node's own flags (ROS's remapping arguments, name:=value, are left to
// ROS), then ros::init under the name `name()` gives once the flags are
// known (a worker is placedb_worker_<i>; __name:= still overrides it). A bad
// flag prints one line and exits 1, --help exits 0. Every node takes
// --verbose (debug logging; an error line names where placedb raised it).
// SIGTERM stops the node as SIGINT does (its spin returns, it reports and
// exits 0). Returns false when the node should exit with `*exit_code`.
bool Init(int* argc, char** argv, const std::function<std::string()>& name, CLI::App& app,
          int* exit_code);

// Ends the node's help with `examples` (one command a line). (Each node's
// CLI::App is named after its program, {description, "placedb_feed"}, so
// that its usage line names it.)
void AddExamples(CLI::App& app, const std::vector<std::string>& examples);

// Runs a node's work and returns its exit code: an exception becomes one line
// "<program>: error: <message>" (option names as flags) and the code of its
// kind, as the placedb binary does (cli/errors.h: 1 input, 74 I/O, 70 a bug).
int RunNode(const std::string& program, const std::function<int()>& work);

// Pins the whole process to CPU `cpu` (before its threads start: they
// inherit it) and logs it; -1 leaves it alone. Throws InvalidArgument for a
// CPU that does not exist, IoError when the kernel refuses.
void PinToCpu(int cpu);

// Logs a dropped message once per cause (and every 100th repeat), so a
// stream of bad messages cannot flood the log.
class DropLog {
 public:
  explicit DropLog(std::string node) : node_(std::move(node)) {}
  void Drop(const std::string& cause, const std::string& detail);
  uint64_t dropped() const { return total_; }
  // Drops by cause.
  const std::map<std::string, uint64_t>& counts() const { return counts_; }
  // "none", or "late 3, database 1" (causes in name order).
  std::string Summary() const;

 private:
  std::string node_;
  std::map<std::string, uint64_t> counts_;
  uint64_t total_ = 0;
};

// The cause of an exception message "cause: detail" (its text up to ':',
// at most 48 bytes): what a drop is counted under.
std::string CauseOf(const std::string& message);

// Wall-clock time, milliseconds since the epoch (comparable across nodes on
// one machine, for latency measurements).
double WallMs();

}  // namespace ros_node
}  // namespace placedb
