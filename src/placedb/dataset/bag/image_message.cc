#include "placedb/dataset/bag/image_message.h"

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/image_encodings.h>

#include "placedb/util/check.h"
#include "placedb/util/file_io.h"

namespace placedb {
namespace enc = sensor_msgs::image_encodings;

cv::Mat ImageMessageToBgr(const sensor_msgs::Image& image) {
  int channels = 0;
  if (image.encoding == enc::MONO8) {
    channels = 1;
  } else if (image.encoding == enc::BGR8 || image.encoding == enc::RGB8) {
    channels = 3;
  } else if (image.encoding == enc::BGRA8 || image.encoding == enc::RGBA8) {
    channels = 4;
  } else {
    PLACEDB_THROW_INVALID("image encoding '", EscapeForTerminal(image.encoding.substr(0, 32)),
                          "' is not mono8, bgr8, rgb8, bgra8 or rgba8");
  }
  if (image.width < 1 || image.height < 1 || image.width > 16384 || image.height > 16384) {
    PLACEDB_THROW_INVALID("image size ", image.width, "x", image.height, " is not in [1, 16384]");
  }
  const uint64_t row = uint64_t{image.width} * channels;
  if (image.step < row || image.step > 4 * row + 64) {
    PLACEDB_THROW_INVALID("image data: row step ", image.step, " does not fit rows of ", row,
                          " bytes");
  }
  if (image.data.size() != uint64_t{image.step} * image.height) {
    PLACEDB_THROW_INVALID("image data: ", image.data.size(), " bytes for ", image.height,
                          " rows of ", image.step);
  }
  try {
    return cv_bridge::toCvCopy(image, enc::BGR8)->image;
  } catch (const std::exception& e) {
    PLACEDB_THROW_INVALID("image data: ", e.what());
  }
}

sensor_msgs::Image BgrToImageMessage(const cv::Mat& image, const std_msgs::Header& header) {
  if (image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3)) {
    PLACEDB_THROW_INVALID("an image message needs an 8-bit gray or BGR image (got ",
                          image.channels(), " channels of depth ", image.depth(), ")");
  }
  return *cv_bridge::CvImage(header, image.channels() == 1 ? enc::MONO8 : enc::BGR8, image)
              .toImageMsg();
}

}  // namespace placedb
