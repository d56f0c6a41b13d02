#include "placedb/ros/testbed.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include "placedb/util/check.h"
#include "placedb/util/file_io.h"

namespace placedb {
namespace fs = std::filesystem;

int LoopbackRos::FreeLoopbackPort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) PLACEDB_THROW_IO("cannot open a socket: ", std::strerror(errno));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  socklen_t len = sizeof(addr);
  const bool ok = ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) == 0 &&
                  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) == 0;
  ::close(fd);
  if (!ok) PLACEDB_THROW_IO("cannot find a free port on 127.0.0.1");
  return ntohs(addr.sin_port);
}

LoopbackRos::LoopbackRos(std::string dir, std::string nodes_dir, RosHost master)
    : dir_(std::move(dir)), nodes_dir_(std::move(nodes_dir)), master_host_(std::move(master)) {
  fs::create_directories(fs::path(dir_) / "ros_home" / "log");
  // Free here; in a namespace of the test's own, every port is.
  port_ = FreeLoopbackPort();
  const std::string uri = "http://" + master_host_.ip + ":" + std::to_string(port_);
  ::setenv("ROS_MASTER_URI", uri.c_str(), 1);
  ::setenv("ROS_IP", master_host_.ip.c_str(), 1);
  ::unsetenv("ROS_HOSTNAME");
  ::setenv("ROS_HOME", (fs::path(dir_) / "ros_home").c_str(), 1);
  ::setenv("ROS_LOG_DIR", (fs::path(dir_) / "ros_home" / "log").c_str(), 1);
  master_ = Start({"rosmaster", "--core", "-p", std::to_string(port_)}, "master.log");
  started_.clear();  // the master is stopped last, by the destructor
}

LoopbackRos::~LoopbackRos() {
  StopNodes();
  Stop(master_);
}

pid_t LoopbackRos::Start(std::vector<std::string> args, const std::string& log,
                         const std::string& ns, const std::optional<RosHost>& on) {
  const RosHost& host = on ? *on : master_host_;
  const std::string local = (fs::path(nodes_dir_) / args[0]).string();
  if (fs::exists(local)) args[0] = local;
  if (!host.netns.empty()) args.insert(args.begin(), {"ip", "netns", "exec", host.netns});
  const std::string out = (fs::path(dir_) / log).string();
  const pid_t pid = ::fork();
  if (pid < 0) PLACEDB_THROW_IO("cannot start ", args[0], ": ", std::strerror(errno));
  if (pid == 0) {
    if (!ns.empty()) ::setenv("ROS_NAMESPACE", ns.c_str(), 1);
    ::setenv("ROS_IP", host.ip.c_str(), 1);
    const int fd = ::open(out.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    if (fd >= 0) {
      ::dup2(fd, 1);
      ::dup2(fd, 2);
    }
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execvp(argv[0], argv.data());
    ::_exit(127);
  }
  started_.push_back(pid);
  return pid;
}

void LoopbackRos::Stop(pid_t pid) {
  if (pid <= 0) return;
  if (::waitpid(pid, nullptr, WNOHANG) != 0) return;  // gone already
  ::kill(pid, SIGTERM);
  for (int i = 0; i < 500; ++i) {
    if (::waitpid(pid, nullptr, WNOHANG) == pid) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ::kill(pid, SIGKILL);
  ::waitpid(pid, nullptr, 0);
}

int LoopbackRos::WaitExit(pid_t pid, double seconds) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < until) {
    int status = 0;
    if (::waitpid(pid, &status, WNOHANG) == pid)
      return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return -1;
}

bool LoopbackRos::Alive(pid_t pid) { return ::waitpid(pid, nullptr, WNOHANG) == 0; }

void LoopbackRos::StopNodes() {
  for (const pid_t pid : started_) Stop(pid);
  started_.clear();
}

std::vector<nlohmann::json> LoopbackRos::ReadJsonLines(const std::string& path) {
  std::vector<nlohmann::json> out;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    if (!line.empty()) out.push_back(nlohmann::json::parse(line));
  }
  return out;
}

std::string LoopbackRos::ReadLog(const std::string& log) const {
  std::string text;
  DirectoryHandle(dir_).ReadFile(log, &text, 64 << 20);
  return text;
}

}  // namespace placedb
