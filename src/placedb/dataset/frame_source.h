// Where frames come from: an image folder or list, or a TUM RGB-D folder,
// with a range of frame ids and optionally a simulated camera size. One
// options struct for every client (the CLI's --images/--tum/--first/...,
// Python's images=/tum=/first=/...), read by ReadFrames. (Bags need ROS:
// dataset/bag/bag_source.h.)
#pragma once

#include <opencv2/core/types.hpp>
#include <string>
#include <vector>

#include "placedb/dataset/frame.h"
#include "placedb/dataset/tum.h"
#include "placedb/util/option_table.h"

namespace placedb {

struct FrameSourceOptions {
  // A folder of images (sorted by name) or a text file listing image paths.
  std::string images;
  // Or a TUM RGB-D folder (rgb.txt, groundtruth.txt).
  std::string tum;
  // Frames first..last of the listing (1-based; last 0: to the end). Range
  // first >= 1, last >= 0, and the range must select a frame. Default all.
  int first = 1;
  int last = 0;
  // Resize every frame to this size as it is read, to see how a smaller
  // camera does (e.g. 160 x 120); 0 x 0: as stored. Each side in
  // [16, 16384], width x height at most image_read.max_pixels.
  cv::Size frame_size;
  TumOptions tum_options;
  ImageReadOptions image_read;

  static const OptionTable<FrameSourceOptions>& Table();
  std::string Check() const;
  // Whether a source is given (images or tum).
  bool empty() const { return images.empty() && tum.empty(); }
};

// The frames of `source` (Check()ed; InvalidArgument when neither or both
// of images and tum are given, NotFound for a missing folder or list).
std::vector<Frame> ReadFrames(const FrameSourceOptions& source);
// "images:DIR [41..84] at 160x120", "tum:DIR [5..]": for manifests and
// reports.
std::string DescribeFrameSource(const FrameSourceOptions& source);
// "WxH" (e.g. "160x120") -> a size with each side in [16, 16384];
// InvalidArgument naming `name` otherwise.
cv::Size ParseFrameSize(const std::string& text, const std::string& name);

}  // namespace placedb
