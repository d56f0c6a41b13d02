#include "placedb/ros/node_common.h"

#include <sched.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <thread>

#include "placedb/util/check.h"

namespace placedb {
namespace ros_node {

bool Init(int* argc, char** argv, const std::function<std::string()>& name, CLI::App& app,
          int* exit_code) {
  // Logs go to files: line by line, so that none is lost when the node is
  // stopped.
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  std::vector<std::string> args;
  ros::removeROSArgs(*argc, argv, args);
  const std::string program = app.get_name().empty() ? "placedb node" : app.get_name();
  try {
    std::vector<std::string> reversed(args.rbegin(), args.rend() - 1);  // CLI11 wants them reversed
    app.parse(reversed);
  } catch (const CLI::CallForHelp& e) {
    *exit_code = app.exit(e);
    return false;
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "%s: error: %s (see --help)\n", argv[0], e.what());
    *exit_code = 1;
    return false;
  }
  ros::init(*argc, argv, name());
  return true;
}

void PinToCpu(int cpu) {
  if (cpu < 0) return;
  const long cpus = ::sysconf(_SC_NPROCESSORS_CONF);
  if (cpu >= cpus) PLACEDB_THROW_INVALID("--cpu ", cpu, ": this machine has CPUs 0 to ", cpus - 1);
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  if (::sched_setaffinity(0, sizeof(set), &set) != 0) {
    PLACEDB_THROW_RUNTIME("cannot pin to CPU ", cpu, ": ", std::strerror(errno));
  }
}

void DropLog::Drop(const std::string& cause, const std::string& detail) {
  const uint64_t n = ++counts_[cause];
  ++total_;
  if (n == 1 || n % 100 == 0) {
    // "(cause: detail)", the cause once even when the detail starts with it.
    const std::string text =
        detail.compare(0, cause.size(), cause) == 0 ? detail : cause + ": " + detail;
    ROS_WARN("%s: dropped a message (%s)%s", node_.c_str(), text.c_str(),
             n == 1 ? "; further drops for this cause are counted"
                    : (" [" + std::to_string(n) + " so far]").c_str());
  }
}

std::string CauseOf(const std::string& message) {
  // Library messages start with "placedb/...cc:123: "; the cause follows.
  std::string m = message;
  const size_t code = m.find(".cc:");
  if (code != std::string::npos) {
    const size_t after = m.find(": ", code);
    if (after != std::string::npos) m = m.substr(after + 2);
  }
  const size_t colon = m.find(':');
  return m.substr(0, std::min<size_t>(colon == std::string::npos ? m.size() : colon, 48));
}

double WallMs() {
  return std::chrono::duration<double, std::milli>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace ros_node
}  // namespace placedb
