// A frame: one image of a sequence with its id, timestamp and, when known, its
// ground-truth pose. Produced by the dataset readers, consumed by build/query.
#pragma once

#include <functional>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "placedb/util/pose.h"

namespace placedb {

struct Frame {
  int id = 0;               // 1-based position in the source listing (folder, list file, rgb.txt)
  double timestamp = -1.0;  // seconds; -1 when unknown
  std::string image_path;   // absolute or as given, usable with cv::imread; or a
                            // description of where `load` reads from
  // When set, reads the image instead of cv::imread(image_path): frames from
  // a bag. Must be callable from several threads at once.
  std::function<cv::Mat()> load;
  std::optional<Pose> pose;  // ground-truth camera pose (camera-to-world), when known
  // When not empty, the image is brought to this size as it is read: a
  // smaller camera, simulated (area interpolation down, bilinear up).
  cv::Size resize_to;
};

// Reads a frame's image as 8-bit BGR (resized to frame.resize_to when set);
// an empty Mat when it cannot be read or decoded.
cv::Mat LoadFrameImage(const Frame& frame);

// Frames first..last of a listing (1-based positions; last 0: to the end).
// std::invalid_argument, naming `what` ("TUM frame", "bag frame"), for
// first < 1, last < 0 or a range that selects nothing.
std::vector<Frame> SelectFrameRange(std::vector<Frame> frames, int first, int last,
                                    const std::string& what);

// How a range is written in source descriptions (manifests, reports):
// " [first..last]", " [first..]", or "" for the whole listing.
std::string FrameRangeSuffix(int first, int last);

// Sets resize_to on every frame.
void ResizeFramesTo(std::vector<Frame>* frames, cv::Size size);

}  // namespace placedb
