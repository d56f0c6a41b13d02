#include "placedb/dataset/bag/bag_source.h"

#include <fmt/format.h>
#include <ros/serialization.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <spdlog/spdlog.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <opencv2/imgcodecs.hpp>

#include "placedb/dataset/bag/bag_reader.h"
#include "placedb/dataset/bag/image_message.h"
#include "placedb/dataset/frame.h"
#include "placedb/dataset/tum.h"
#include "placedb/util/check.h"
#include "placedb/util/file_io.h"
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

// A serialized ROS message walked field by field: every length it states is
// checked against the bytes left before anything is read or allocated
// (ROS's deserialization resizes a vector to a stated length first).
class MessageCursor {
 public:
  MessageCursor(const uint8_t* data, size_t size) : data_(data), left_(size) {}
  bool Skip(size_t n) {
    if (n > left_) return false;
    data_ += n;
    left_ -= n;
    return true;
  }
  bool U32(uint32_t* v) {
    if (left_ < 4) return false;
    std::memcpy(v, data_, 4);
    return Skip(4);
  }
  // A string or uint8[]: a 4-byte length and that many bytes.
  bool Sized() {
    uint32_t n = 0;
    return U32(&n) && Skip(n);
  }
  bool Header() { return Skip(12) && Sized(); }  // seq, stamp, frame_id
  size_t left() const { return left_; }

 private:
  const uint8_t* data_;
  size_t left_;
};

bool ImageLayout(const uint8_t* data, size_t size) {
  MessageCursor c(data, size);
  // header, height, width, encoding, is_bigendian, step, data
  return c.Header() && c.Skip(8) && c.Sized() && c.Skip(5) && c.Sized() && c.left() == 0;
}

bool CompressedImageLayout(const uint8_t* data, size_t size) {
  MessageCursor c(data, size);
  return c.Header() && c.Sized() && c.Sized() && c.left() == 0;  // header, format, data
}

bool TfMessageLayout(const uint8_t* data, size_t size) {
  MessageCursor c(data, size);
  uint32_t n = 0;
  if (!c.U32(&n)) return false;
  // Each transform: a header, child_frame_id, 7 float64 (at least 76 bytes).
  if (n > c.left() / 76) return false;
  for (uint32_t i = 0; i < n; ++i) {
    if (!c.Header() || !c.Sized() || !c.Skip(56)) return false;
  }
  return c.left() == 0;
}

// A message of type M from its bytes, once `layout` holds for them.
template <typename M>
M Deserialize(const uint8_t* data, size_t size) {
  M message;
  ros::serialization::IStream stream(const_cast<uint8_t*>(data), static_cast<uint32_t>(size));
  ros::serialization::deserialize(stream, message);
  return message;
}

enum class ImageKind { kNone, kRaw, kCompressed };

// What a connection holds, from its type and definition's checksum: an
// image of our sensor_msgs, or something else (kNone). A type of ours with
// another checksum is another definition of it: refused.
template <typename M>
bool IsType(const BagConnection& c, const std::string& bag) {
  if (c.type != ros::message_traits::DataType<M>::value()) return false;
  const std::string md5 = ros::message_traits::MD5Sum<M>::value();
  if (c.md5sum != md5 && c.md5sum != "*") {
    PLACEDB_THROW_INVALID("the bag ", bag, ": topic ", EscapeForTerminal(c.topic), " holds ",
                          c.type, " of another definition (checksum ",
                          EscapeForTerminal(c.md5sum.substr(0, 32)), ", this placedb reads ", md5,
                          ")");
  }
  return true;
}

ImageKind KindOf(const BagConnection& c, const std::string& bag) {
  if (IsType<sensor_msgs::Image>(c, bag)) return ImageKind::kRaw;
  if (IsType<sensor_msgs::CompressedImage>(c, bag)) return ImageKind::kCompressed;
  return ImageKind::kNone;
}

[[noreturn]] void BadMessage(const std::string& bag, const BagConnection& c, const BagMessage& m) {
  PLACEDB_THROW_INVALID("the bag ", bag, ": a ", c.type, " message on ", EscapeForTerminal(c.topic),
                        " (recorded at ", m.sec, ".", fmt::format("{:09d}", m.nsec), " s, ", m.size,
                        " bytes) does not hold the fields its type has (lengths that do not "
                        "fit): a damaged bag or a message of another type");
}

// An image message's header stamp (0 when it has none), from a message
// whose layout was checked (it starts with seq, sec, nsec).
double ImageStamp(const uint8_t* data) {
  uint32_t stamp[3];
  std::memcpy(stamp, data, 12);
  return stamp[1] + stamp[2] * 1e-9;
}

struct OpenBag {
  std::unique_ptr<BagReader> reader;
  std::string topic;
};

cv::Mat Decode(const OpenBag& open, const BagMessage& m, ImageKind kind, const std::string& shown) {
  try {
    const std::string bytes = open.reader->ReadMessage(m);
    const auto* data = reinterpret_cast<const uint8_t*>(bytes.data());
    if (kind == ImageKind::kRaw) {
      if (!ImageLayout(data, bytes.size()))
        PLACEDB_THROW_INVALID("the message's lengths do not fit");
      return ImageMessageToBgr(Deserialize<sensor_msgs::Image>(data, bytes.size()));
    }
    if (!CompressedImageLayout(data, bytes.size())) {
      PLACEDB_THROW_INVALID("the message's lengths do not fit");
    }
    const auto compressed = Deserialize<sensor_msgs::CompressedImage>(data, bytes.size());
    // Bounded by the header's pixel count before decoding; empty when
    // undecodable or too large.
    DecodedImage d =
        DecodeImage(compressed.data.data(), compressed.data.size(), ImageReadOptions(), shown);
    if (!d.error.empty()) spdlog::warn("{}", d.error);
    return d.image;
  } catch (const std::exception& e) {
    spdlog::warn("{}: {}", shown, e.what());
  }
  return cv::Mat();
}

}  // namespace

std::vector<Frame> ReadBagFrames(const BagSourceOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  std::error_code ec;
  if (!std::filesystem::exists(options.bag, ec))
    PLACEDB_THROW_NOT_FOUND("no bag file at ", options.bag);
  if (!std::filesystem::is_regular_file(options.bag, ec))
    PLACEDB_THROW_INVALID("the bag ", options.bag, " is not a file");
  auto open = std::make_shared<OpenBag>();
  open->topic = options.topic;
  struct Found {
    BagMessage message;
    ImageKind kind;
    double stamp;
  };
  std::vector<Found> found;
  std::vector<TumPoseStamped> poses;
  auto strip = [](const std::string& s) { return s.empty() || s[0] != '/' ? s : s.substr(1); };
  const bool want_tf = options.groundtruth.empty() && !options.tf_parent.empty();
  std::map<uint32_t, ImageKind> kinds;  // of the connections on the image topic
  open->reader = std::make_unique<BagReader>(
      options.bag,
      [&](const BagMessage& m, const BagConnection& c, const uint8_t* data, size_t size) {
        if (c.topic == options.topic) {
          auto it = kinds.find(c.id);
          if (it == kinds.end()) it = kinds.emplace(c.id, KindOf(c, options.bag)).first;
          if (it->second == ImageKind::kNone) return;
          const bool fits = it->second == ImageKind::kRaw ? ImageLayout(data, size)
                                                          : CompressedImageLayout(data, size);
          if (!fits) BadMessage(options.bag, c, m);
          const double stamp = ImageStamp(data);
          found.push_back({m, it->second, stamp > 0 ? stamp : m.time()});
        } else if (want_tf && c.topic == options.tf_topic &&
                   c.type == ros::message_traits::DataType<tf2_msgs::TFMessage>::value()) {
          if (!IsType<tf2_msgs::TFMessage>(c, options.bag)) return;
          if (!TfMessageLayout(data, size)) BadMessage(options.bag, c, m);
          const auto msg = Deserialize<tf2_msgs::TFMessage>(data, size);
          for (const auto& t : msg.transforms) {
            if (strip(t.header.frame_id) != strip(options.tf_parent) ||
                strip(t.child_frame_id) != strip(options.tf_child)) {
              continue;
            }
            TumPoseStamped p;
            p.timestamp = t.header.stamp.toSec();
            p.pose.translation = Eigen::Vector3d(
                t.transform.translation.x, t.transform.translation.y, t.transform.translation.z);
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
      });
  if (found.empty()) {
    PLACEDB_THROW_INVALID(options.bag, ": no sensor_msgs/Image or CompressedImage messages on ",
                          options.topic);
  }
  // In the order they were recorded, as rosbag's views give them.
  std::stable_sort(found.begin(), found.end(), [](const Found& a, const Found& b) {
    return a.message.time() < b.message.time();
  });
  std::vector<Frame> frames;
  frames.reserve(found.size());
  for (const Found& x : found) {
    Frame f;
    f.id = static_cast<int>(frames.size()) + 1;
    f.timestamp = x.stamp;
    f.image_path = options.bag + ":" + options.topic + "#" + std::to_string(f.id);
    f.load = [open, m = x.message, kind = x.kind, shown = f.image_path] {
      return Decode(*open, m, kind, shown);
    };
    frames.push_back(std::move(f));
  }
  std::string from;
  if (!options.groundtruth.empty()) {
    poses = ReadTumTrajectory(options.groundtruth);
    from = options.groundtruth;
  } else if (!options.tf_parent.empty()) {
    from = options.tf_topic + " " + options.tf_parent + " -> " + options.tf_child;
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

}  // namespace placedb
