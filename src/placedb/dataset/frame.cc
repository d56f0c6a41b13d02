#include "placedb/dataset/frame.h"

#include <fmt/format.h>

#include <algorithm>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "placedb/util/check.h"

namespace placedb {

cv::Mat LoadFrameImage(const Frame& frame) {
  cv::Mat image = frame.load ? frame.load() : cv::imread(frame.image_path, cv::IMREAD_COLOR);
  if (image.empty() || frame.resize_to.empty() || image.size() == frame.resize_to) return image;
  const bool down = frame.resize_to.area() < image.size().area();
  cv::Mat resized;
  cv::resize(image, resized, frame.resize_to, 0, 0, down ? cv::INTER_AREA : cv::INTER_LINEAR);
  return resized;
}

std::vector<Frame> SelectFrameRange(std::vector<Frame> frames, int first, int last,
                                    const std::string& what) {
  if (first < 1) PLACEDB_THROW_INVALID("first must be >= 1, got ", first);
  if (last < 0) PLACEDB_THROW_INVALID("last must be >= 0 (0: to the end), got ", last);
  const size_t begin = static_cast<size_t>(first - 1);
  const size_t end = last == 0 ? frames.size() : std::min(frames.size(), static_cast<size_t>(last));
  if (begin >= frames.size() || begin >= end) {
    PLACEDB_THROW_INVALID("first/last select no ", what, " (", frames.size(), " listed)");
  }
  return std::vector<Frame>(frames.begin() + static_cast<ptrdiff_t>(begin),
                            frames.begin() + static_cast<ptrdiff_t>(end));
}

std::string FrameRangeSuffix(int first, int last) {
  if (first == 1 && last == 0) return "";
  return last == 0 ? fmt::format(" [{}..]", first) : fmt::format(" [{}..{}]", first, last);
}

void ResizeFramesTo(std::vector<Frame>* frames, cv::Size size) {
  for (Frame& f : *frames) f.resize_to = size;
}

}  // namespace placedb
