// Frames straight from a ROS bag (TUM distributes its sequences as bags), for
// `placedb build/eval/bench --bag FILE --topic T`. This header has no ROS
// includes: the CLI uses it whether or not it was built with ROS (when not,
// ReadBagFrames says so).
#pragma once

#include <string>
#include <vector>

#include "placedb/dataset/frame.h"

namespace placedb {

struct BagSourceOptions {
  // The bag file and the image topic in it: sensor_msgs/Image (mono8, bgr8,
  // rgb8, bgra8, rgba8) or sensor_msgs/CompressedImage.
  std::string bag;
  std::string topic;
  // Poses, optional, either from a TUM trajectory file ("timestamp tx ty tz
  // qx qy qz qw" lines) ...
  std::string groundtruth;
  // ... or from the bag's /tf (tf2_msgs/TFMessage): the transform from
  // tf_parent to tf_child (e.g. "world" and "kinect"), as published.
  std::string tf_parent;
  std::string tf_child;
  std::string tf_topic = "/tf";
  // Largest |t_image - t_pose| for a frame to get a pose, seconds. Range
  // [0, 3600]. Default 0.02 (as TUM's associate.py).
  double max_time_difference = 0.02;

  std::string Check() const;
};

// The images on the topic, in bag order: id = 1-based position, timestamp =
// the message header's stamp (the bag's receive time when it is 0), a pose
// when one is within max_time_difference, image_path = "bag:topic#id", and a
// `load` that decodes the message (thread-safe; the bag stays open while any
// frame lives). Errors: NotFound for a missing bag; InvalidArgument for bad
// options, a topic with no image messages, a damaged bag or message;
// IoError when the bag cannot be read; a build without ROS says so.
std::vector<Frame> ReadBagFrames(const BagSourceOptions& options);

}  // namespace placedb
