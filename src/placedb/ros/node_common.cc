#include "placedb/ros/node_common.h"

#include <sched.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <thread>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "placedb/cli/errors.h"

namespace placedb {
namespace ros_node {
namespace {
// --verbose, for RunNode's error line (a node parses its flags once).
bool verbose = false;

// SIGTERM as roscpp's SIGINT handler: ask the node to shut down.
void OnSigterm(int) { ros::requestShutdown(); }
}  // namespace

void AddExamples(CLI::App& app, const std::vector<std::string>& examples) {
  std::string footer = examples.size() == 1 ? "Example:" : "Examples:";
  for (const std::string& e : examples) footer += "\n  " + e;
  app.footer(footer);
}

bool Init(int* argc, char** argv, const std::function<std::string()>& name, CLI::App& app,
          int* exit_code) {
  // Logs go to files: line by line, so that none is lost when the node is
  // stopped.
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  std::vector<std::string> args;
  ros::removeROSArgs(*argc, argv, args);
  app.add_flag("--verbose", verbose,
               "debug logging; an error line also names where in placedb it was raised");
  try {
    std::vector<std::string> reversed(args.rbegin(), args.rend() - 1);  // CLI11 wants them reversed
    app.parse(reversed);
  } catch (const CLI::CallForHelp& e) {
    *exit_code = app.exit(e);
    return false;
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "%s: error: %s (see --help)\n", app.get_name().c_str(), e.what());
    *exit_code = cli::kExitInput;
    return false;
  } catch (...) {
    // A flag's value the option table refused (InvalidArgument naming it).
    *exit_code = cli::ReportCurrentException(app.get_name(), verbose);
    return false;
  }
  if (verbose) spdlog::set_level(spdlog::level::debug);
  ros::init(*argc, argv, name());
  std::signal(SIGTERM, OnSigterm);
  return true;
}

int RunNode(const std::string& program, const std::function<int()>& work) {
  try {
    return work();
  } catch (...) {
    return cli::ReportCurrentException(program, verbose);
  }
}

void PinToCpu(int cpu) {
  if (cpu < 0) return;
  const long cpus = ::sysconf(_SC_NPROCESSORS_CONF);
  if (cpu >= cpus) {
    throw InvalidArgument(fmt::format("`cpu` {}: this machine has CPUs 0 to {}", cpu, cpus - 1));
  }
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  if (::sched_setaffinity(0, sizeof(set), &set) != 0) {
    throw IoError(fmt::format("cannot pin to CPU {}: {}", cpu, std::strerror(errno)));
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

std::string DropLog::Summary() const {
  if (counts_.empty()) return "none";
  std::string text;
  for (const auto& [cause, n] : counts_) text += (text.empty() ? "" : ", ") + cause + " " + std::to_string(n);
  return text;
}

std::string CauseOf(const std::string& message) {
  // Library messages carry no source location (it is in Error::where()):
  // the cause is their first words.
  const size_t colon = message.find(':');
  return message.substr(0,
                        std::min<size_t>(colon == std::string::npos ? message.size() : colon, 48));
}

double WallMs() {
  return std::chrono::duration<double, std::milli>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace ros_node
}  // namespace placedb
