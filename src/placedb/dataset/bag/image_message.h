// sensor_msgs/Image to and from OpenCV, with every field of an incoming image
// checked first (a message from the wire is untrusted).
#pragma once

#include <sensor_msgs/Image.h>

#include <opencv2/core.hpp>
#include <string>

namespace placedb {

// The image as 8-bit BGR. Accepted encodings: mono8, bgr8, rgb8, bgra8,
// rgba8. Throws InvalidArgument whose message starts with the cause
// ("image encoding", "image size", "image data") for anything else: another
// encoding, an empty or oversized image (sides in [1, 16384]), a row step
// below the row's bytes, data of the wrong length.
cv::Mat ImageMessageToBgr(const sensor_msgs::Image& image);

// An 8-bit BGR (or gray) image as a message (bgr8 / mono8), header given;
// any other image is InvalidArgument.
sensor_msgs::Image BgrToImageMessage(const cv::Mat& image, const std_msgs::Header& header);

}  // namespace placedb
