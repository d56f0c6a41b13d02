#include "placedb/dataset/frame.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace placedb {

cv::Mat LoadFrameImage(const Frame& frame) {
  cv::Mat image = frame.load ? frame.load() : cv::imread(frame.image_path, cv::IMREAD_COLOR);
  if (image.empty() || frame.resize_to.empty() || image.size() == frame.resize_to) return image;
  const bool down = frame.resize_to.area() < image.size().area();
  cv::Mat resized;
  cv::resize(image, resized, frame.resize_to, 0, 0, down ? cv::INTER_AREA : cv::INTER_LINEAR);
  return resized;
}

void ResizeFramesTo(std::vector<Frame>* frames, cv::Size size) {
  for (Frame& f : *frames) f.resize_to = size;
}

}  // namespace placedb
