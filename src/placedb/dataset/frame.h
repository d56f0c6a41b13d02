// A frame: one image of a sequence with its id, timestamp and, when known, its
// ground-truth pose. Produced by the dataset readers, consumed by build/query.
#pragma once

#include <optional>
#include <string>

#include "placedb/util/pose.h"

namespace placedb {

struct Frame {
  int id = 0;                // 1-based position in the source listing (folder, list file, rgb.txt)
  double timestamp = -1.0;   // seconds; -1 when unknown
  std::string image_path;    // absolute or as given, usable with cv::imread
  std::optional<Pose> pose;  // ground-truth camera pose (camera-to-world), when known
};

}  // namespace placedb
