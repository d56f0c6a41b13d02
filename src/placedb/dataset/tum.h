// Readers for TUM RGB-D benchmark folders
// (https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats): rgb.txt lists the colour
// images, groundtruth.txt the camera poses; frames get the ground-truth pose nearest in time, as
// TUM's associate.py does.
#pragma once

#include <string>
#include <vector>

#include "placedb/dataset/frame.h"
#include "placedb/util/pose.h"
#include "placedb/util/option_table.h"

namespace placedb {

struct TumOptions {
  // Largest |t_image - t_pose| for a frame to get a pose, seconds; default 0.02
  // like associate.py. Frames with no pose that close are kept, pose-less.
  double max_time_difference = 0.02;
  // Image list inside the folder, default "rgb.txt": "timestamp relative/path.png" lines.
  std::string rgb_list = "rgb.txt";
  // Ground-truth file inside the folder, default "groundtruth.txt"; may be absent.
  std::string groundtruth = "groundtruth.txt";

  // Empty when valid, else the reason.
  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<TumOptions>& Table();
  std::string Check() const;
};

struct TumPoseStamped {
  double timestamp = 0.0;  // seconds
  Pose pose;               // camera-to-world; quaternion normalised
};

// Reads a TUM trajectory ("timestamp tx ty tz qx qy qz qw" lines, '#'
// comments), in file order. Malformed lines (field count, non-numeric token,
// quaternion norm off 1 by more than 1e-2) → InvalidArgument naming the file
// and line; quaternions within tolerance are normalised. Missing file →
// NotFound; unreadable → IoError.
std::vector<TumPoseStamped> ReadTumTrajectory(const std::string& path);

// Gives each frame the pose of `poses` nearest to its timestamp (ties: the
// earlier pose) when within `max_time_difference` seconds; returns how many
// frames got none.
size_t AssignNearestPoses(std::vector<Frame>* frames, std::vector<TumPoseStamped> poses,
                          double max_time_difference);

// Frames of a TUM RGB-D folder: id = 1-based position among the frames listed
// in rgb.txt (file order), timestamp from rgb.txt, image_path = dir/relative
// path. Each frame gets the ground-truth pose nearest in time (ties: the
// earlier pose) if |dt| <= max_time_difference, else no pose (kept; one
// summary warning). groundtruth.txt missing → every frame pose-less, with one
// warning. Errors: NotFound for a missing dir or rgb.txt; InvalidArgument for
// malformed lines (file:line) or no frames. A listed image that does not exist
// is kept with a warning (file:line).
std::vector<Frame> ReadTumSequence(const std::string& dir,
                                   const TumOptions& options = TumOptions());

}  // namespace placedb
