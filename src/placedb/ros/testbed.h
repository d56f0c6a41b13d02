// A ROS system on loopback for tests and benchmarks: a master on a free
// 127.0.0.1 port with its own ROS_HOME and log folder (this process's
// environment is pointed at it), nodes started as processes, and everything
// stopped by PID with SIGTERM (SIGKILL after 5 s) when the testbed goes.
// A process may run on another "host": a network namespace the test made,
// entered with `ip netns exec`, advertising that namespace's address.
#pragma once

#include <sys/types.h>

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace placedb {

// Where a process runs: in network namespace `netns` (empty: this process's
// own), with ROS_IP `ip`, the address the node advertises.
struct RosHost {
  std::string netns;
  std::string ip = "127.0.0.1";
};

class LoopbackRos {
 public:
  // Starts rosmaster on `master` (by default 127.0.0.1 here); `dir` holds
  // ROS_HOME, the logs and the nodes' output. `nodes_dir` is where the
  // placedb_* executables are. ROS_MASTER_URI and ROS_IP of this process
  // (and of every process it starts) point at the master's host.
  LoopbackRos(std::string dir, std::string nodes_dir, RosHost master = {});
  ~LoopbackRos();
  LoopbackRos(const LoopbackRos&) = delete;
  LoopbackRos& operator=(const LoopbackRos&) = delete;

  int port() const { return port_; }
  const std::string& dir() const { return dir_; }
  // Starts a node of ours by its bare name (placedb_worker ...), or a
  // command on the PATH, in ROS namespace `ns` on `host` (by default the
  // master's), its output appended to dir/`log`. Returns its PID (stopped
  // with the testbed; `ip netns exec` becomes the command, not its parent).
  pid_t Start(std::vector<std::string> args, const std::string& log, const std::string& ns = "",
              const std::optional<RosHost>& host = std::nullopt);
  // Stops one process (SIGTERM, then SIGKILL after 5 s).
  static void Stop(pid_t pid);
  // Its exit code when it ends within `seconds`, else -1.
  static int WaitExit(pid_t pid, double seconds);
  static bool Alive(pid_t pid);
  // Stops every process started so far (the master stays).
  void StopNodes();
  // The text of dir/`log`.
  std::string ReadLog(const std::string& log) const;

  // A free TCP port on 127.0.0.1.
  static int FreeLoopbackPort();
  // The JSON lines a node wrote (--answers-file, --log-file).
  static std::vector<nlohmann::json> ReadJsonLines(const std::string& path);

 private:
  std::string dir_, nodes_dir_;
  RosHost master_host_;
  int port_ = 0;
  pid_t master_ = -1;
  std::vector<pid_t> started_;
};

}  // namespace placedb
