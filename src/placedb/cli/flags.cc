#include "placedb/cli/flags.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <iostream>

#include "placedb/cli/options.h"
#ifdef PLACEDB_WITH_ROS
#include "placedb/dataset/bag/bag_source.h"
#endif
#include "placedb/util/check.h"
#include "placedb/util/file_io.h"

namespace placedb {
namespace cli {

namespace {

class PlacedbHelpFormatter : public CLI::Formatter {
 public:
  std::string make_option_name(const CLI::Option* opt, bool is_positional) const override {
    std::string name = CLI::Formatter::make_option_name(opt, is_positional);
    for (const char* marker : {"{false}", "{true}"}) {
      for (size_t at = name.find(marker); at != std::string::npos; at = name.find(marker))
        name.erase(at, std::string(marker).size());
    }
    return name;
  }
};

}  // namespace

std::shared_ptr<CLI::Formatter> HelpFormatter() {
  return std::make_shared<PlacedbHelpFormatter>();
}

void SourceArgs::Add(CLI::App* cmd) {
  AddOptionFlags(cmd, &source);
  CLI::Option* images = cmd->get_option("--images");
  CLI::Option* tum = cmd->get_option("--tum");
  images->excludes(tum);
  CLI::Option* bag_opt = cmd->add_option(
      "--bag", bag, "a ROS bag (needs a build with ROS); the images on --topic");
  bag_opt->excludes(images)->excludes(tum);
  cmd->add_option("--topic", topic, "bag: the image topic (sensor_msgs/Image or CompressedImage)");
  cmd->add_option("--bag-groundtruth", bag_groundtruth, "bag: poses from this TUM trajectory file");
  cmd->add_option("--bag-tf", bag_tf,
                  "bag: poses from /tf, the transform PARENT,CHILD (e.g. world,kinect)");
}

std::vector<Frame> SourceArgs::Read() const {
  if (bag.empty()) return ReadFrames(source);
#ifdef PLACEDB_WITH_ROS
  PLACEDB_CHECK_OPTIONS(source);
  BagSourceOptions o;
  o.bag = bag;
  o.topic = topic;
  o.groundtruth = bag_groundtruth;
  o.max_time_difference = source.tum_options.max_time_difference;
  if (!bag_tf.empty()) {
    const size_t comma = bag_tf.find(',');
    if (comma == std::string::npos) PLACEDB_THROW_INVALID("--bag-tf takes PARENT,CHILD");
    o.tf_parent = bag_tf.substr(0, comma);
    o.tf_child = bag_tf.substr(comma + 1);
  }
  std::vector<Frame> frames =
      SelectFrameRange(ReadBagFrames(o), source.first, source.last, "bag frame");
  SetImageReadOptions(&frames, source.image_read);
  if (!source.frame_size.empty()) ResizeFramesTo(&frames, source.frame_size);
  return frames;
#else
  PLACEDB_THROW_INVALID(
      "this placedb was built without ROS (-DPLACEDB_WITH_ROS=OFF): --bag is not available");
#endif
}

std::string SourceArgs::Describe() const {
  if (!bag.empty()) return "bag:" + bag + ":" + topic + FrameRangeSuffix(source.first, source.last);
  return DescribeFrameSource(source);
}

void QueryArgs::Add(CLI::App* cmd, const std::vector<std::string>& skip) {
  AddOptionFlags(cmd, &options, skip);
}

QueryOptions QueryArgs::Get() const {
  PLACEDB_CHECK_OPTIONS(options);
  return options;
}

void DatabaseArgs::Add(CLI::App* cmd, bool threads) {
  cmd->add_option("--db", dir, "database directory")->required();
  std::vector<std::string> skip;
  if (!threads) skip.push_back("threads");
  AddOptionFlags(cmd, &open, skip);
  cmd->get_option("--keyframes")->excludes(cmd->get_option("--partition"));
}

void DatabaseArgs::AddDirectoryOnly(CLI::App* cmd) {
  cmd->add_option("--db", dir, "database directory")->required();
}

PlaceDatabase DatabaseArgs::Open() const { return PlaceDatabase::Open(dir, open); }

namespace {

// The descriptor of the original stdout once ReserveStdoutForJson moved the
// human text away (-1 before), and the --json path that named it.
int json_stdout_fd = -1;
std::string json_stdout_path;

// Whether `path` is the file stdout is: a FIFO, a tty, a regular file.
bool IsStdout(const std::string& path) {
  if (path == "-") return true;
  struct stat named, out;
  return ::stat(path.c_str(), &named) == 0 && ::fstat(STDOUT_FILENO, &out) == 0 &&
         named.st_dev == out.st_dev && named.st_ino == out.st_ino;
}

}  // namespace

bool ReserveStdoutForJson(const std::string& json_path) {
  if (json_path.empty() || json_stdout_fd >= 0 || !IsStdout(json_path)) return false;
  std::fflush(stdout);
  std::cout.flush();
  const int fd = ::fcntl(STDOUT_FILENO, F_DUPFD_CLOEXEC, 3);
  if (fd < 0) return false;
  // fd 1 becomes stderr: fmt::print, printf and std::cout all follow.
  if (::dup2(STDERR_FILENO, STDOUT_FILENO) < 0) {
    ::close(fd);
    return false;
  }
  // Line by line, as stderr is read: the human text keeps its place
  // beside the log lines.
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  json_stdout_fd = fd;
  json_stdout_path = json_path;
  return true;
}

void WriteJson(const std::string& path, const std::string& json) {
  if (path.empty()) return;
  if (json_stdout_fd >= 0 && path == json_stdout_path) {
    std::fflush(stdout);
    const std::string text = json + "\n";
    if (!WriteAll(json_stdout_fd, text.data(), text.size()))
      PLACEDB_THROW_IO("cannot write the JSON to stdout: ", std::strerror(errno));
    return;
  }
  if (path == "-") {
    std::cout << json << "\n" << std::flush;
    return;
  }
  WriteFileAtomic(path, json + "\n");
  spdlog::info("wrote {}", path);
}

std::string FormatPose(const std::optional<Pose>& pose) {
  if (!pose) return "(no pose)";
  const auto& t = pose->translation;
  const auto& q = pose->rotation;
  return fmt::format("t = ({:.4f}, {:.4f}, {:.4f}) m, q = ({:.4f}, {:.4f}, {:.4f}, {:.4f})", t.x(),
                     t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
}

}  // namespace cli
}  // namespace placedb
