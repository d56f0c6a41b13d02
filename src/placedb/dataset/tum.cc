#include "placedb/dataset/tum.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <system_error>

#include "placedb/dataset/text_lines.h"
#include "placedb/util/check.h"

namespace placedb {
namespace {

namespace fs = std::filesystem;

constexpr double kQuaternionNormTolerance = 1e-2;

// Index of the pose nearest in time to `t` in `poses` (sorted by time, not
// empty); ties go to the earlier pose.
size_t NearestPose(const std::vector<TumPoseStamped>& poses, double t) {
  const auto after =
      std::lower_bound(poses.begin(), poses.end(), t,
                       [](const TumPoseStamped& p, double time) { return p.timestamp < time; });
  if (after == poses.begin()) return 0;
  if (after == poses.end()) return poses.size() - 1;
  const auto before = after - 1;
  const bool take_before = t - before->timestamp <= after->timestamp - t;
  return static_cast<size_t>((take_before ? before : after) - poses.begin());
}

}  // namespace

size_t AssignNearestPoses(std::vector<Frame>* frames, std::vector<TumPoseStamped> poses,
                          double max_time_difference) {
  if (poses.empty()) return frames->size();
  std::stable_sort(
      poses.begin(), poses.end(),
      [](const TumPoseStamped& a, const TumPoseStamped& b) { return a.timestamp < b.timestamp; });
  size_t poseless = 0;
  for (Frame& frame : *frames) {
    const TumPoseStamped& nearest = poses[NearestPose(poses, frame.timestamp)];
    if (std::abs(nearest.timestamp - frame.timestamp) <= max_time_difference) {
      frame.pose = nearest.pose;
    } else {
      ++poseless;
    }
  }
  return poseless;
}

std::vector<TumPoseStamped> ReadTumTrajectory(const std::string& path) {
  std::vector<TumPoseStamped> poses;
  for (const internal::TextLine& line : internal::ReadDataLines(path, "TUM trajectory")) {
    const std::vector<std::string> fields = internal::SplitFields(line.text, " \t");
    if (fields.size() != 8) {
      internal::ThrowLineError(path, line.number,
                               "expected 8 numbers (timestamp tx ty tz qx qy qz qw), got " +
                                   std::to_string(fields.size()));
    }
    static const char* kNames[8] = {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};
    double v[8];
    for (int i = 0; i < 8; ++i)
      v[i] = internal::ParseDouble(fields[i], path, line.number, kNames[i]);
    TumPoseStamped stamped;
    stamped.timestamp = v[0];
    stamped.pose.translation = Eigen::Vector3d(v[1], v[2], v[3]);
    stamped.pose.rotation = Eigen::Quaterniond(v[7], v[4], v[5], v[6]);  // (w, x, y, z)
    const double norm = stamped.pose.rotation.norm();
    if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
      internal::ThrowLineError(
          path, line.number, "quaternion (qx qy qz qw) is not unit: norm " + std::to_string(norm));
    }
    stamped.pose.rotation.normalize();
    poses.push_back(stamped);
  }
  return poses;
}

std::vector<Frame> ReadTumSequence(const std::string& dir, const TumOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    if (!fs::exists(dir, ec)) {
      PLACEDB_THROW_NOT_FOUND(dir, " does not exist (`tum` takes a TUM RGB-D folder)");
    }
    PLACEDB_THROW_INVALID(dir, " is not a folder (`tum` takes a TUM RGB-D folder; an image list "
                               "is read with `images`)");
  }
  const std::string rgb_path = (fs::path(dir) / options.rgb_list).string();
  if (!fs::exists(rgb_path, ec)) {
    PLACEDB_THROW_NOT_FOUND("not a TUM RGB-D folder: ", options.rgb_list, " not found in ", dir,
                            " (a folder of images is read with `images`)");
  }

  std::vector<Frame> frames;
  for (const internal::TextLine& line : internal::ReadDataLines(rgb_path, "TUM image list")) {
    const std::vector<std::string> fields = internal::SplitFields(line.text, " \t");
    if (fields.size() != 2) {
      internal::ThrowLineError(
          rgb_path, line.number,
          "expected 2 fields (timestamp filename), got " + std::to_string(fields.size()));
    }
    Frame frame;
    frame.id = static_cast<int>(frames.size()) + 1;
    frame.timestamp = internal::ParseDouble(fields[0], rgb_path, line.number, "timestamp");
    frame.image_path = (fs::path(dir) / fields[1]).string();
    if (!internal::IsRegularFile(frame.image_path)) {
      // Kept, so ids stay positions in rgb.txt; the build skips and counts it.
      spdlog::warn("{}:{}: image not found: {}", rgb_path, line.number, frame.image_path);
    }
    frames.push_back(std::move(frame));
  }
  if (frames.empty()) PLACEDB_THROW_INVALID(rgb_path, ": no frames listed");

  const std::string gt_path = (fs::path(dir) / options.groundtruth).string();
  if (!fs::exists(gt_path, ec)) {
    spdlog::warn("{}: no ground truth ({} not found); all {} frames are pose-less", dir,
                 options.groundtruth, frames.size());
    return frames;
  }
  std::vector<TumPoseStamped> poses = ReadTumTrajectory(gt_path);
  if (poses.empty()) {
    spdlog::warn("{}: {} has no poses; all {} frames are pose-less", dir, options.groundtruth,
                 frames.size());
    return frames;
  }
  const size_t poseless =
      AssignNearestPoses(&frames, std::move(poses), options.max_time_difference);
  if (poseless > 0) {
    spdlog::warn("{}: {} of {} frames have no ground-truth pose within {} s; kept pose-less", dir,
                 poseless, frames.size(), options.max_time_difference);
  }
  return frames;
}

}  // namespace placedb
