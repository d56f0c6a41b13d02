#include "placedb/dataset/bag/bag_source.h"

#include <rosbag/bag.h>
#include <rosbag/exceptions.h>
#include <rosbag/view.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <spdlog/spdlog.h>
#include <tf2_msgs/TFMessage.h>

#include <filesystem>
#include <memory>
#include <mutex>
#include <opencv2/imgcodecs.hpp>

#include "placedb/dataset/frame.h"
#include "placedb/dataset/tum.h"
#include "placedb/dataset/bag/image_message.h"
#include "placedb/util/check.h"
#include "placedb/util/options.h"

namespace placedb {

std::string BagSourceOptions::Check() const {
  if (bag.empty()) return "bag: no bag file given";
  if (topic.empty()) return "topic: no image topic given";
  if (tf_parent.empty() != tf_child.empty()) return "tf: give both the parent and the child frame";
  if (!groundtruth.empty() && !tf_parent.empty())
    return "poses: give a ground-truth file or /tf, not both";
  return CheckRange("max_time_difference", max_time_difference, 0.0, 3600.0);
}

namespace {

// The open bag and the image messages in it; reads are serialised (rosbag
// is not thread-safe).
struct OpenBag {
  rosbag::Bag bag;
  std::unique_ptr<rosbag::View> view;
  std::vector<rosbag::MessageInstance> messages;
  std::mutex mutex;
};

cv::Mat Decode(OpenBag& open, size_t index, const std::string& shown) {
  std::lock_guard<std::mutex> lock(open.mutex);
  const rosbag::MessageInstance& m = open.messages[index];
  try {
    if (const auto image = m.instantiate<sensor_msgs::Image>()) return ImageMessageToBgr(*image);
    if (const auto compressed = m.instantiate<sensor_msgs::CompressedImage>()) {
      // Bounded by the header's pixel count before decoding; empty when
      // undecodable or too large.
      DecodedImage d = DecodeImage(compressed->data.data(), compressed->data.size(),
                                   ImageReadOptions(), shown);
      if (!d.error.empty()) spdlog::warn("{}", d.error);
      return d.image;
    }
  } catch (const std::exception& e) {
    spdlog::warn("{}: {}", shown, e.what());
  }
  return cv::Mat();
}

std::vector<Frame> ReadFrames(const BagSourceOptions& options);

}  // namespace

std::vector<Frame> ReadBagFrames(const BagSourceOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  std::error_code ec;
  if (!std::filesystem::exists(options.bag, ec))
    PLACEDB_THROW_NOT_FOUND("no bag file at ", options.bag);
  if (!std::filesystem::is_regular_file(options.bag, ec))
    PLACEDB_THROW_INVALID("the bag ", options.bag, " is not a file");
  // rosbag throws its own exceptions from opening and from every chunk it
  // reads (the views are read lazily): a failed read is the system's, any
  // other is a bag that is damaged or not a bag, the user's input.
  try {
    return ReadFrames(options);
  } catch (const rosbag::BagIOException& e) {
    PLACEDB_THROW_IO("cannot read the bag ", options.bag, ": ", e.what());
  } catch (const rosbag::BagException& e) {
    PLACEDB_THROW_INVALID("cannot read the bag ", options.bag, ": ", e.what());
  }
}

namespace {

std::vector<Frame> ReadFrames(const BagSourceOptions& options) {
  auto open = std::make_shared<OpenBag>();
  open->bag.open(options.bag, rosbag::bagmode::Read);
  open->view = std::make_unique<rosbag::View>(open->bag, rosbag::TopicQuery(options.topic));
  std::vector<Frame> frames;
  for (const rosbag::MessageInstance& m : *open->view) {
    const std::string type = m.getDataType();
    if (type != "sensor_msgs/Image" && type != "sensor_msgs/CompressedImage") continue;
    double stamp = m.getTime().toSec();
    try {
      if (const auto image = m.instantiate<sensor_msgs::Image>()) {
        if (!image->header.stamp.isZero()) stamp = image->header.stamp.toSec();
      } else if (const auto compressed = m.instantiate<sensor_msgs::CompressedImage>()) {
        if (!compressed->header.stamp.isZero()) stamp = compressed->header.stamp.toSec();
      }
    } catch (const std::exception& e) {
      PLACEDB_THROW_INVALID(options.bag, ": a message on ", options.topic,
                            " cannot be read: ", e.what());
    }
    Frame f;
    f.id = static_cast<int>(frames.size()) + 1;
    f.timestamp = stamp;
    f.image_path = options.bag + ":" + options.topic + "#" + std::to_string(f.id);
    const size_t index = open->messages.size();
    open->messages.push_back(m);
    f.load = [open, index, shown = f.image_path] { return Decode(*open, index, shown); };
    frames.push_back(std::move(f));
  }
  if (frames.empty()) {
    PLACEDB_THROW_INVALID(options.bag, ": no sensor_msgs/Image or CompressedImage messages on ",
                          options.topic);
  }
  std::vector<TumPoseStamped> poses;
  std::string from;
  if (!options.groundtruth.empty()) {
    poses = ReadTumTrajectory(options.groundtruth);
    from = options.groundtruth;
  } else if (!options.tf_parent.empty()) {
    from = options.tf_topic + " " + options.tf_parent + " -> " + options.tf_child;
    auto strip = [](const std::string& s) { return s.empty() || s[0] != '/' ? s : s.substr(1); };
    rosbag::View tf(open->bag, rosbag::TopicQuery(options.tf_topic));
    for (const rosbag::MessageInstance& m : tf) {
      const auto msg = m.instantiate<tf2_msgs::TFMessage>();
      if (!msg) continue;
      for (const auto& t : msg->transforms) {
        if (strip(t.header.frame_id) != strip(options.tf_parent) ||
            strip(t.child_frame_id) != strip(options.tf_child)) {
          continue;
        }
        TumPoseStamped p;
        p.timestamp = t.header.stamp.toSec();
        p.pose.translation = Eigen::Vector3d(t.transform.translation.x, t.transform.translation.y,
                                             t.transform.translation.z);
        p.pose.rotation = Eigen::Quaterniond(t.transform.rotation.w, t.transform.rotation.x,
                                             t.transform.rotation.y, t.transform.rotation.z);
        if (!p.pose.translation.allFinite() || !p.pose.rotation.coeffs().allFinite() ||
            std::abs(p.pose.rotation.norm() - 1.0) > 1e-2) {
          continue;  // not a pose
        }
        p.pose.rotation.normalize();
        poses.push_back(p);
      }
    }
    if (poses.empty()) spdlog::warn("{}: no transform {} in the bag", options.bag, from);
  }
  if (!from.empty()) {
    const size_t poseless =
        AssignNearestPoses(&frames, std::move(poses), options.max_time_difference);
    if (poseless > 0) {
      spdlog::warn("{}: {} of {} frames have no pose from {} within {} s; kept pose-less",
                   options.bag, poseless, frames.size(), from, options.max_time_difference);
    }
  }
  return frames;
}

}  // namespace

}  // namespace placedb
