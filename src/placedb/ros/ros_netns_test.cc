// The paper's Fig. 3 across machines, each "machine" a network namespace this
// test makes: the master, the feed, the voters and this process in one
// (host m), two workers in each of two others (hosts a and b). Each host is
// joined by a veth pair to a bridge in a fourth namespace (the switch), with
// an address that exists only inside these namespaces (10.77.0.1, .2, .3/24).
// Every node runs under `ip netns exec HOST`, with ROS_IP its host's address
// and ROS_MASTER_URI the master's, as on real machines; each worker host has
// its own copy of the database directory.
//
// The namespaces are named placedb-<pid>-<host>, so parallel runs do not
// collide; they, and with them the links, are deleted when the suite ends,
// failed or not, and a run first deletes those a crashed run left (their
// PID is gone). Where namespaces cannot be made (not root, no `ip`, `ip netns
// add` refused), every test skips with the reason.
//
// As in ros_system_test, nothing races a clock: the tests wait for events
// (links as the publishing node reports them, lines in answers files), each
// with a limit that only ends a hang.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sched.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "placedb/builder/builder.h"
#include "placedb/dataset/image_folder.h"
#include "placedb/ros/system_testing.h"
#include "placedb/ros/testbed.h"

namespace placedb {
namespace {
namespace fs = std::filesystem;
using ros_testing::ExpectSameAnswer;
using ros_testing::kNoDeadline;
using ros_testing::kRunLimit;
using ros_testing::WaitLines;
using ros_testing::WaitLinked;
using ros_testing::WaitUntil;

const std::string kImages = PLACEDB_DATA_DIR "/rtabmap_loop/images";
const std::string kNodes = std::string(PLACEDB_ROS_TREE) + "/lib/placedb/";
const std::string kNetnsDir = "/var/run/netns";  // where `ip netns add` names them
const std::string kPrefix = "placedb-";  // then <pid>-<host>

// The `ip` of iproute2: on the PATH, or where Debian puts it (a PATH
// without the sbin folders is common for tests).
std::string FindIp() {
  std::vector<std::string> dirs = {"/usr/sbin", "/sbin", "/usr/bin", "/bin"};
  if (const char* path = std::getenv("PATH")) {
    std::string p = path;
    for (size_t at = 0, end; at <= p.size(); at = end + 1) {
      end = p.find(':', at);
      if (end == std::string::npos) end = p.size();
      dirs.insert(dirs.begin(), p.substr(at, end - at));
    }
  }
  for (const std::string& d : dirs) {
    const fs::path ip = fs::path(d.empty() ? "." : d) / "ip";
    if (::access(ip.c_str(), X_OK) == 0) return ip.string();
  }
  return "";
}

// Three hosts on one switch, as the file's comment says.
class Hosts {
 public:
  struct Host {
    std::string name;  // m, a, b
    std::string ip;
  };

  explicit Hosts(std::string log) : log_(std::move(log)), tag_(kPrefix + std::to_string(::getpid()) + "-") {}
  ~Hosts() { Remove(); }
  Hosts(const Hosts&) = delete;
  Hosts& operator=(const Hosts&) = delete;

  // Makes the namespaces and their links; "" or why they cannot be made.
  std::string Make() {
    if (::geteuid() != 0)
      return "not root (uid " + std::to_string(::geteuid()) +
             "): network namespaces need CAP_NET_ADMIN and CAP_SYS_ADMIN";
    ip_ = FindIp();
    if (ip_.empty()) return "no `ip` (iproute2) on the PATH or in /usr/sbin, /sbin";
    // The testbed starts nodes with `ip netns exec`, found on the PATH.
    const std::string path = std::getenv("PATH") ? std::getenv("PATH") : "";
    ::setenv("PATH", (path + ":" + fs::path(ip_).parent_path().string()).c_str(), 1);
    SweepStale();
    const std::string sw = Netns("sw");
    if (Ip({"netns", "add", sw}) != 0) return "`ip netns add " + sw + "` failed: " + LastError();
    made_.push_back(sw);
    std::vector<std::vector<std::string>> steps = {
        {"-n", sw, "link", "add", "br0", "type", "bridge"},
        {"-n", sw, "link", "set", "br0", "up"}};
    for (const Host& h : hosts_) {
      const std::string ns = Netns(h.name), port = "port-" + h.name;
      if (Ip({"netns", "add", ns}) != 0) return "`ip netns add " + ns + "` failed: " + LastError();
      made_.push_back(ns);
      steps.push_back({"-n", ns, "link", "set", "lo", "up"});
      steps.push_back({"-n", ns, "link", "add", "veth0", "type", "veth", "peer", "name", port,
                       "netns", sw});
      steps.push_back({"-n", sw, "link", "set", port, "master", "br0"});
      steps.push_back({"-n", sw, "link", "set", port, "up"});
      steps.push_back({"-n", ns, "addr", "add", h.ip + "/24", "dev", "veth0"});
      steps.push_back({"-n", ns, "link", "set", "veth0", "up"});
    }
    // Last, what every node's start does (it needs to mount /sys, which a
    // container may refuse).
    steps.push_back({"netns", "exec", Netns("m"), "true"});
    for (const std::vector<std::string>& step : steps) {
      if (Ip(step) != 0) {
        std::string line = "ip";
        for (const std::string& s : step) line += " " + s;
        return "`" + line + "` failed: " + LastError();
      }
    }
    return "";
  }

  // Deletes what Make made (a namespace goes when its last process has).
  void Remove() {
    for (auto it = made_.rbegin(); it != made_.rend(); ++it) Ip({"netns", "delete", *it});
    made_.clear();
  }

  std::string Netns(const std::string& host) const { return tag_ + host; }
  const Host& host(const std::string& name) const {
    for (const Host& h : hosts_) {
      if (h.name == name) return h;
    }
    throw std::out_of_range(name);
  }
  RosHost Ros(const std::string& name) const { return RosHost{Netns(name), host(name).ip}; }

 private:
  // Runs ip with `args`, its output appended to the log; its exit code.
  int Ip(const std::vector<std::string>& args) {
    std::ofstream(log_, std::ios::app) << "ip " << ::testing::PrintToString(args) << "\n";
    const pid_t pid = ::fork();
    if (pid < 0) return -1;
    if (pid == 0) {
      const int fd = ::open(log_.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      if (fd >= 0) {
        ::dup2(fd, 1);
        ::dup2(fd, 2);
      }
      std::vector<std::string> all = {ip_};
      all.insert(all.end(), args.begin(), args.end());
      std::vector<char*> argv;
      for (std::string& a : all) argv.push_back(a.data());
      argv.push_back(nullptr);
      ::execv(argv[0], argv.data());
      ::_exit(127);
    }
    int status = 0;
    ::waitpid(pid, &status, 0);
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
  }
  // The last line ip wrote.
  std::string LastError() const {
    std::ifstream in(log_);
    std::string line, last;
    while (std::getline(in, line)) {
      if (!line.empty()) last = line;
    }
    return last;
  }
  // Deletes namespaces of this test whose run is gone (a crash, a timeout's
  // SIGKILL), or that carry this PID from a run before.
  void SweepStale() {
    std::error_code ec;
    for (const fs::directory_entry& e : fs::directory_iterator(kNetnsDir, ec)) {
      const std::string name = e.path().filename().string();
      if (name.rfind(kPrefix, 0) != 0) continue;
      const std::string rest = name.substr(kPrefix.size());
      const size_t dash = rest.find('-');
      if (dash == 0 || dash == std::string::npos ||
          rest.find_first_not_of("0123456789") != dash)
        continue;
      const pid_t pid = static_cast<pid_t>(std::stol(rest.substr(0, dash)));
      if (pid == ::getpid() || (::kill(pid, 0) != 0 && errno == ESRCH))
        Ip({"netns", "delete", name});
    }
  }

  std::string log_, tag_, ip_;
  std::vector<Host> hosts_ = {{"m", "10.77.0.1"}, {"a", "10.77.0.2"}, {"b", "10.77.0.3"}};
  std::vector<std::string> made_;
};

class RosAcrossHostsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() /
                        ("placedb_ros_netns_" + std::to_string(::getpid())));
    fs::remove_all(*dir_);
    fs::create_directories(*dir_);
    hosts_ = new Hosts((*dir_ / "ip.log").string());
    skip_ = new std::string(hosts_->Make());
    if (!skip_->empty()) return;
    // This process joins host m (its threads, roscpp's included, start
    // later and follow); it goes back to its own namespace at the end.
    home_netns_ = ::open("/proc/self/ns/net", O_RDONLY | O_CLOEXEC);
    const std::string m = kNetnsDir + "/" + hosts_->Netns("m");
    const int fd = ::open(m.c_str(), O_RDONLY | O_CLOEXEC);
    if (home_netns_ < 0 || fd < 0 || ::setns(fd, CLONE_NEWNET) != 0) {
      *skip_ = "cannot enter " + m + ": " + std::strerror(errno);
      if (fd >= 0) ::close(fd);
      return;
    }
    ::close(fd);
    ros_ = new LoopbackRos(dir_->string(), kNodes, hosts_->Ros("m"));
    // The database (images 1-40), and a copy for each worker host.
    BuildOptions build;
    build.threads = 2;
    build.progress = false;
    BuildDatabase(ListImageFolder(kImages, 1, 40), build, Db("m"), "rtabmap 1..40");
    for (const std::string h : {"a", "b"}) {
      fs::create_directories(*dir_ / h);
      fs::copy(Db("m"), Db(h), fs::copy_options::recursive);
    }
    int argc = 1;
    char name[] = "ros_netns_test";
    char* argv[] = {name, nullptr};
    ros::init(argc, argv, "ros_netns_test", ros::init_options::NoSigintHandler);
    ASSERT_TRUE(WaitUntil([] { return ros::master::check(); }))
        << "rosmaster did not start on " << hosts_->host("m").ip << ":" << ros_->port() << "\n"
        << ros_->ReadLog("master.log");
    ready_ = true;
  }
  static void TearDownTestSuite() {
    if (ros_ != nullptr) {
      ros::shutdown();
      delete ros_;
      ros_ = nullptr;
    }
    if (home_netns_ >= 0) {
      ::setns(home_netns_, CLONE_NEWNET);
      ::close(home_netns_);
      home_netns_ = -1;
    }
    delete hosts_;  // deletes the namespaces
    hosts_ = nullptr;
    fs::remove_all(*dir_);
    delete dir_;
    delete skip_;
  }
  void SetUp() override {
    if (!skip_->empty()) GTEST_SKIP() << "network namespaces cannot be made: " << *skip_;
    ASSERT_TRUE(ready_) << "the hosts, the master or the database did not come up (above)";
  }
  void TearDown() override {
    if (ros_ != nullptr) ros_->StopNodes();
  }

  // Host h's copy of the database (m's is the one built).
  static std::string Db(const std::string& h) {
    return (h == "m" ? *dir_ / "db" : *dir_ / h / "db").string();
  }
  static std::string Path(const std::string& name) { return (*dir_ / name).string(); }
  // The host of partition i of 4: a holds 0 and 1, b holds 2 and 3.
  static std::string HostOf(int partition) { return partition < 2 ? "a" : "b"; }
  static pid_t Start(const std::vector<std::string>& args, const std::string& log,
                     const std::string& ns, const std::string& host) {
    return ros_->Start(args, log, ns, hosts_->Ros(host));
  }
  static std::string ReadLog(const std::string& log) { return ros_->ReadLog(log); }
  // Node `name` registered with the master at its host's address.
  static ::testing::AssertionResult At(const std::string& name, const std::string& host) {
    const std::string uri = ros_testing::NodeUri(name);
    if (uri.rfind("http://" + hosts_->host(host).ip + ":", 0) == 0)
      return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure() << name << " registered " << uri << ", not on host "
                                         << host << " (" << hosts_->host(host).ip << ")";
  }

  static fs::path* dir_;
  static Hosts* hosts_;
  static std::string* skip_;
  static LoopbackRos* ros_;
  static int home_netns_;
  static bool ready_;
};
fs::path* RosAcrossHostsTest::dir_ = nullptr;
Hosts* RosAcrossHostsTest::hosts_ = nullptr;
std::string* RosAcrossHostsTest::skip_ = nullptr;
LoopbackRos* RosAcrossHostsTest::ros_ = nullptr;
int RosAcrossHostsTest::home_netns_ = -1;
bool RosAcrossHostsTest::ready_ = false;

// The feed and the voter on host m, workers 0 and 1 on host a and 2 and 3 on
// host b (interleaved, pinned): every node registers its host's address, and
// every answer is complete and equals the single-process query of the same
// image. (The voter waits for every partition, the feed for each answer; the
// feed starts when every link is up: 4 workers + this process's gate.)
TEST_F(RosAcrossHostsTest, AnswersEqualTheSingleProcessQuery) {
  const std::string ns = "/hosts";
  Start({"placedb_voter", "--db", Db("m"), "--partitions", "4", "--partition-scheme",
         "interleaved", "--deadline-ms", kNoDeadline, "--answers-file", Path("hosts_answers.jsonl")},
        "hosts_voter.log", ns, "m");
  std::vector<std::string> workers;
  for (int i = 0; i < 4; ++i) {
    Start({"placedb_worker", "--db", Db(HostOf(i)), "--partition", std::to_string(i) + "/4",
           "--partition-scheme", "interleaved", "--cpu", std::to_string(i % 2)},
          "hosts_worker" + std::to_string(i) + ".log", ns, HostOf(i));
    workers.push_back(ns + "/placedb_worker_" + std::to_string(i));
  }
  const pid_t feed = Start({"placedb_feed", "--images", kImages, "--first", "41", "--wait-for", "5",
                            "--rate", "0", "--answer-timeout-ms", kNoDeadline},
                           "hosts_feed.log", ns, "m");
  ASSERT_TRUE(WaitLinked(workers, ns + "/partial_results", {ns + "/placedb_voter"}))
      << ReadLog("hosts_voter.log") << ReadLog("hosts_worker0.log") << ReadLog("hosts_worker2.log");
  ASSERT_TRUE(WaitLinked({ns + "/placedb_voter"}, ns + "/answers", {ns + "/placedb_feed"}))
      << ReadLog("hosts_feed.log");
  EXPECT_TRUE(At(ns + "/placedb_voter", "m"));
  EXPECT_TRUE(At(ns + "/placedb_feed", "m"));
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(At(workers[i], HostOf(i)));
  const ros::Subscriber gate = ros_testing::OpenGate(ns);
  ASSERT_EQ(LoopbackRos::WaitExit(feed, kRunLimit), 0) << ReadLog("hosts_feed.log");
  const std::vector<nlohmann::json> answers = WaitLines(Path("hosts_answers.jsonl"), 44);
  ASSERT_EQ(answers.size(), 44u) << ReadLog("hosts_voter.log");
  const std::vector<QueryResult> expected = ros_testing::SingleProcess(Db("m"), kImages, 41, 84);
  for (const nlohmann::json& a : answers) {
    const uint64_t seq = a["frame_seq"];
    ASSERT_LT(seq, 44u);
    EXPECT_TRUE(a["complete"].get<bool>()) << "frame " << seq;
    ExpectSameAnswer(a, expected[seq], "frame " + std::to_string(seq));
  }
}

// Host b's workers (partitions 2 and 3) killed together, as if the machine
// went down: frames are answered around them by the deadline, flagged
// partial and naming both; restarted on host b, they rejoin and answers are
// complete again (ros_testing::RunKillDrill, the voters and this process's
// frames on host m).
TEST_F(RosAcrossHostsTest, AHostGoneIsAnsweredAroundAndRejoins) {
  const std::string ns = "/hostfaults";
  ros_testing::KillDrill drill;
  drill.ns = ns;
  drill.db = Db("m");
  drill.images = kImages;
  drill.files = Path("hostfaults_");
  drill.partitions = 4;
  drill.killed = {2, 3};
  drill.start_voter = [&](const std::vector<std::string>& args, const std::string& name) {
    return Start(args, "hostfaults_" + name + ".log", ns, "m");
  };
  drill.start_worker = [&](int i, const std::string& name) {
    return Start({"placedb_worker", "--db", Db(HostOf(i)), "--partition", std::to_string(i) + "/4",
                  "__name:=" + name},
                 "hostfaults_" + name + ".log", ns, HostOf(i));
  };
  drill.read_log = [](const std::string& name) { return ReadLog("hostfaults_" + name + ".log"); };
  ros_testing::RunKillDrill(drill);
}

}  // namespace
}  // namespace placedb
