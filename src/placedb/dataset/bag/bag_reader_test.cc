// Bags as `rosbag record` writes them (rosbag_storage, each compression),
// and bags crafted byte by byte: hostile sizes, messages of another type,
// damage anywhere. Every bag is read through ReadBagFrames, the --bag source.
#include <gtest/gtest.h>
#include <ros/serialization.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <tf2_msgs/TFMessage.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <functional>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>
#include <vector>

#include "placedb/dataset/bag/bag_source.h"
#include "placedb/dataset/bag/image_message.h"
#include "placedb/exe/cli_testing.h"
#include "placedb/util/check.h"
#include "placedb/util/file_io.h"
#include "placedb/util/testing.h"

namespace placedb {
namespace {

using testing_util::Contains;
using testing_util::ThrowsWith;

// ---- a bag written byte by byte (format 2.0, one uncompressed chunk) ----
std::string U32(uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); }
std::string U64(uint64_t v) { return std::string(reinterpret_cast<const char*>(&v), 8); }
std::string Field(const std::string& name, const std::string& value) {
  return U32(static_cast<uint32_t>(name.size() + 1 + value.size())) + name + "=" + value;
}
std::string Record(const std::string& header, const std::string& data) {
  return U32(static_cast<uint32_t>(header.size())) + header +
         U32(static_cast<uint32_t>(data.size())) + data;
}

struct CraftedMessage {
  std::string topic, type, md5sum;
  std::string bytes;  // serialized
  uint32_t sec = 1, nsec = 0;
};

template <typename M>
std::string Serialize(const M& message) {
  std::string out(ros::serialization::serializationLength(message), '\0');
  ros::serialization::OStream stream(reinterpret_cast<uint8_t*>(out.data()),
                                     static_cast<uint32_t>(out.size()));
  ros::serialization::serialize(stream, message);
  return out;
}

template <typename M>
CraftedMessage Crafted(const std::string& topic, const std::string& bytes, uint32_t sec) {
  return {topic,
          ros::message_traits::DataType<M>::value(),
          ros::message_traits::MD5Sum<M>::value(),
          bytes,
          sec,
          0};
}

// One connection per distinct topic, every message in one chunk, then the
// index (connections and the chunk info): what rosbag writes without
// compression.
std::string CraftBag(const std::vector<CraftedMessage>& messages) {
  std::vector<std::string> topics;
  std::vector<const CraftedMessage*> first_of;
  std::string chunk;
  auto connection = [&](uint32_t id, const CraftedMessage& m) {
    return Record(Field("op", "\x07") + Field("conn", U32(id)) + Field("topic", m.topic),
                  Field("topic", m.topic) + Field("type", m.type) + Field("md5sum", m.md5sum) +
                      Field("message_definition", "..."));
  };
  std::vector<std::vector<std::pair<uint64_t, uint32_t>>> index;
  for (const CraftedMessage& m : messages) {
    uint32_t id = 0;
    while (id < topics.size() && topics[id] != m.topic) ++id;
    if (id == topics.size()) {
      topics.push_back(m.topic);
      first_of.push_back(&m);
      index.emplace_back();
      chunk += connection(id, m);
    }
    index[id].emplace_back(uint64_t{m.nsec} << 32 | m.sec, static_cast<uint32_t>(chunk.size()));
    chunk += Record(
        Field("op", "\x02") + Field("conn", U32(id)) + Field("time", U32(m.sec) + U32(m.nsec)),
        m.bytes);
  }
  const std::string magic = "#ROSBAG V2.0\n";
  const size_t header_bytes = 4096;  // rosbag pads its header record to 4096 bytes
  const uint64_t chunk_pos = magic.size() + header_bytes;
  std::string body = Record(Field("op", "\x05") + Field("compression", "none") +
                                Field("size", U32(static_cast<uint32_t>(chunk.size()))),
                            chunk);
  for (uint32_t id = 0; id < topics.size(); ++id) {
    std::string entries;
    for (const auto& [time, offset] : index[id]) entries += U64(time) + U32(offset);
    body += Record(Field("op", "\x04") + Field("ver", U32(1)) + Field("conn", U32(id)) +
                       Field("count", U32(static_cast<uint32_t>(index[id].size()))),
                   entries);
  }
  const uint64_t index_pos = chunk_pos + body.size();
  for (uint32_t id = 0; id < topics.size(); ++id) body += connection(id, *first_of[id]);
  std::string counts;
  for (uint32_t id = 0; id < topics.size(); ++id)
    counts += U32(id) + U32(static_cast<uint32_t>(index[id].size()));
  body += Record(Field("op", "\x06") + Field("ver", U32(1)) + Field("chunk_pos", U64(chunk_pos)) +
                     Field("start_time", U64(0)) + Field("end_time", U64(0)) +
                     Field("count", U32(static_cast<uint32_t>(topics.size()))),
                 counts);
  std::string header = Field("op", "\x03") + Field("index_pos", U64(index_pos)) +
                       Field("conn_count", U32(static_cast<uint32_t>(topics.size()))) +
                       Field("chunk_count", U32(1));
  const std::string padding(header_bytes - 8 - header.size(), ' ');
  return magic + Record(header, padding) + body;
}

sensor_msgs::Image ImageMessage(const cv::Mat& bgr, uint32_t sec) {
  std_msgs::Header h;
  h.stamp = ros::Time(sec, 5);
  h.frame_id = "camera";
  return BgrToImageMessage(bgr, h);
}

cv::Mat Pattern(int seed) {
  cv::Mat m(48, 64, CV_8UC3);
  cv::randu(m, cv::Scalar::all(0), cv::Scalar::all(255));
  m.at<cv::Vec3b>(0, 0) = cv::Vec3b(static_cast<uchar>(seed), 0, 0);
  return m;
}

bool SameImage(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

// Runs `body` in a child process whose address space is limited to
// `limit_bytes` (what a robot's computer has, and a bound on any
// allocation): true when the child returned normally with `body()` true,
// false when it failed, crashed or aborted. Not under the sanitizers (their
// shadow memory needs more address space than any limit allows).
bool InLimitedChild(uint64_t limit_bytes, const std::function<bool()>& body) {
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    struct rlimit limit = {limit_bytes, limit_bytes};
    ::setrlimit(RLIMIT_AS, &limit);
    bool ok = false;
    try {
      ok = body();
    } catch (...) {
      ok = false;
    }
    ::_exit(ok ? 0 : 1);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

constexpr bool kSanitized = testing_util::kThreadSanitizer || testing_util::kAddressSanitizer;

class BagTest : public ::testing::Test {
 protected:
  std::string Path(const std::string& name) const { return tmp_.Path(name); }
  std::vector<Frame> Read(const std::string& bag, const std::string& topic) {
    BagSourceOptions o;
    o.bag = bag;
    o.topic = topic;
    return ReadBagFrames(o);
  }
  testing_util::TempDir tmp_;
};

// What rosbag writes, in each compression: raw and compressed images in
// recording order with their stamps, and poses from /tf.
TEST_F(BagTest, ReadsWhatRosbagWrites) {
  for (const auto compression :
       {rosbag::compression::Uncompressed, rosbag::compression::BZ2, rosbag::compression::LZ4}) {
    const std::string path =
        Path("written" + std::to_string(static_cast<int>(compression)) + ".bag");
    std::vector<cv::Mat> raw, encoded;
    {
      rosbag::Bag bag(path, rosbag::bagmode::Write);
      bag.setCompression(compression);
      bag.setChunkThreshold(4096);  // several chunks
      for (uint32_t i = 0; i < 4; ++i) {
        raw.push_back(Pattern(static_cast<int>(i)));
        bag.write("/camera/image", ros::Time(100 + i), ImageMessage(raw.back(), 10 + i));
        sensor_msgs::CompressedImage c;
        c.header.stamp = ros::Time(20 + i, 0);
        c.format = "png";
        cv::imencode(".png", raw.back(), c.data);
        encoded.push_back(raw.back());
        bag.write("/camera/compressed", ros::Time(100 + i), c);
        tf2_msgs::TFMessage tf;
        geometry_msgs::TransformStamped t;
        t.header.stamp = ros::Time(10 + i, 5);
        t.header.frame_id = "world";
        t.child_frame_id = "camera";
        t.transform.translation.x = i;
        t.transform.rotation.w = 1.0;
        tf.transforms.push_back(t);
        bag.write("/tf", ros::Time(100 + i), tf);
      }
    }
    BagSourceOptions o;
    o.bag = path;
    o.topic = "/camera/image";
    o.tf_parent = "world";
    o.tf_child = "camera";
    const std::vector<Frame> frames = ReadBagFrames(o);
    ASSERT_EQ(frames.size(), 4u);
    for (size_t i = 0; i < frames.size(); ++i) {
      EXPECT_EQ(frames[i].id, static_cast<int>(i) + 1);
      EXPECT_DOUBLE_EQ(frames[i].timestamp, 10 + i + 5e-9);
      EXPECT_TRUE(SameImage(LoadFrameImage(frames[i]), raw[i])) << i;
      ASSERT_TRUE(frames[i].pose.has_value());
      EXPECT_DOUBLE_EQ(frames[i].pose->translation.x(), static_cast<double>(i));
    }
    const std::vector<Frame> compressed = Read(path, "/camera/compressed");
    ASSERT_EQ(compressed.size(), 4u);
    for (size_t i = 0; i < compressed.size(); ++i) {
      EXPECT_DOUBLE_EQ(compressed[i].timestamp, 20.0 + i);
      EXPECT_TRUE(SameImage(LoadFrameImage(compressed[i]), encoded[i])) << i;
    }
    EXPECT_TRUE(ThrowsWith<InvalidArgument>([&] { Read(path, "/tf"); }, "no sensor_msgs/Image"));
  }
}

// The crafted bags of the tests below are bags: rosbag reads one as placedb
// does.
TEST_F(BagTest, CraftedBagsAreWellFormed) {
  const cv::Mat image = Pattern(7);
  const std::string path = Path("crafted.bag");
  WriteFileAtomic(
      path,
      CraftBag({Crafted<sensor_msgs::Image>("/camera", Serialize(ImageMessage(image, 3)), 3)}));
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  rosbag::View view(bag);
  ASSERT_EQ(view.size(), 1u);
  EXPECT_TRUE(view.begin()->instantiate<sensor_msgs::Image>() != nullptr);
  const std::vector<Frame> frames = Read(path, "/camera");
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_TRUE(SameImage(LoadFrameImage(frames[0]), image));
}

// `bag` is refused with `phrase`, and so it is in a process whose address
// space is `limit_bytes` (not under the sanitizers).
void ExpectRefusedWithin(const std::string& bag, const std::string& phrase, uint64_t limit_bytes) {
  auto refused = [&] {
    BagSourceOptions o;
    o.bag = bag;
    o.topic = "/camera";
    return static_cast<bool>(ThrowsWith<InvalidArgument>([&] { ReadBagFrames(o); }, phrase));
  };
  EXPECT_TRUE(refused());
  if (!kSanitized) {
    EXPECT_TRUE(InLimitedChild(limit_bytes, refused));
  }
}

// An Image message's bytes on a CompressedImage topic: read as a
// CompressedImage its data length is four pixel bytes (3.7 GB here), which
// ROS's deserialization would allocate. Refused from the lengths alone, in
// a process that cannot allocate a gigabyte.
TEST_F(BagTest, AnotherTypesBytesAreRefusedBeforeAnyAllocation) {
  const cv::Mat grey(200, 250, CV_8UC3, cv::Scalar::all(0xdd));
  const std::string path = Path("mistyped.bag");
  WriteFileAtomic(path, CraftBag({Crafted<sensor_msgs::CompressedImage>(
                            "/camera", Serialize(ImageMessage(grey, 3)), 3)}));
  ExpectRefusedWithin(path, "does not hold the fields its type has", uint64_t{1} << 30);
}

// A first record whose header states 0xFFFFFFF0 bytes: refused before it is
// allocated (rosbag allocates it, and aborts under a 4 GB limit).
TEST_F(BagTest, AHugeRecordHeaderIsRefusedBeforeAnyAllocation) {
  const std::string path = Path("huge_header.bag");
  WriteFileAtomic(path, "#ROSBAG V2.0\n" + U32(0xFFFFFFF0u) + std::string(200, 'x'));
  ExpectRefusedWithin(path, "a record header of 4294967280 bytes", uint64_t{4} << 30);
}

// The two hostile bags through the CLI, under a 4 GB address-space limit:
// one line, exit 1.
TEST_F(BagTest, HostileBagsGiveOneLineAndExitOneFromTheCli) {
  if (kSanitized) GTEST_SKIP() << "an address-space limit: not under the sanitizers";
  const cv::Mat grey(200, 250, CV_8UC3, cv::Scalar::all(0xdd));
  WriteFileAtomic(Path("mistyped.bag"), CraftBag({Crafted<sensor_msgs::CompressedImage>(
                                            "/camera", Serialize(ImageMessage(grey, 3)), 3)}));
  WriteFileAtomic(Path("huge_header.bag"),
                  "#ROSBAG V2.0\n" + U32(0xFFFFFFF0u) + std::string(200, 'x'));
  for (const char* bag : {"mistyped.bag", "huge_header.bag"}) {
    const testing_util::CommandResult r = testing_util::RunShell(
        "ulimit -v 4000000; " + std::string(PLACEDB_BINARY) + " build --bag " + Path(bag) +
        " --topic /camera --out " + Path("db") + " --quiet 2>&1 >/dev/null");
    EXPECT_EQ(r.code, 1) << bag << ": " << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
    EXPECT_TRUE(Contains(r.output, "placedb: error: ")) << r.output;
  }
}

// Damage anywhere in a bag (bit flips, 4-byte values at aligned offsets,
// truncation), of rosbag's own bags in each compression and of a crafted
// one: each is read and its frames load, or it is refused with
// InvalidArgument; never another error, a crash or (under the sanitizers)
// a bad read.
TEST_F(BagTest, MutatedBagsNeverCrash) {
  std::vector<std::string> originals;
  for (const auto compression :
       {rosbag::compression::Uncompressed, rosbag::compression::BZ2, rosbag::compression::LZ4}) {
    const std::string path = Path("original.bag");
    {
      rosbag::Bag bag(path, rosbag::bagmode::Write);
      bag.setCompression(compression);
      bag.setChunkThreshold(2048);
      for (uint32_t i = 0; i < 3; ++i) {
        cv::Mat small(12, 16, CV_8UC3, cv::Scalar::all(40 * i));
        bag.write("/camera", ros::Time(1 + i), ImageMessage(small, 1 + i));
      }
    }
    originals.push_back(ReadFileToString(path));
  }
  cv::Mat small(12, 16, CV_8UC3, cv::Scalar::all(9));
  sensor_msgs::CompressedImage c;
  cv::imencode(".png", small, c.data);
  c.format = "png";
  originals.push_back(
      CraftBag({Crafted<sensor_msgs::Image>("/camera", Serialize(ImageMessage(small, 1)), 1),
                Crafted<sensor_msgs::CompressedImage>("/c", Serialize(c), 2)}));
  const uint32_t interesting[] = {0,   1,    3,          4,          7,          8,
                                  255, 4096, 0x7fffffff, 0x80000000, 0xfffffff0, 0xffffffff};
  std::mt19937_64 rng(20261207);
  int read = 0, refused = 0;
  spdlog::set_level(spdlog::level::err);  // a warning per undecodable image
  const std::string path = Path("mutated.bag");
  for (int i = 0; i < 1600; ++i) {
    std::string bad = originals[static_cast<size_t>(i) % originals.size()];
    const int kind = static_cast<int>(rng() % 3);
    if (kind == 0) {
      for (int f = 0, n = 1 + static_cast<int>(rng() % 3); f < n; ++f)
        bad[rng() % bad.size()] ^= static_cast<char>(1 << (rng() % 8));
    } else if (kind == 1) {
      const size_t at = 4 * (rng() % (bad.size() / 4));
      const uint32_t v = interesting[rng() % (sizeof(interesting) / 4)];
      std::memcpy(&bad[at], &v, 4);
    } else {
      bad.resize(rng() % bad.size());
    }
    WriteFileAtomic(path, bad);
    try {
      for (const char* topic : {"/camera", "/c"}) {
        try {
          for (const Frame& f : Read(path, topic)) LoadFrameImage(f);
        } catch (const InvalidArgument& e) {
          if (!Contains(e.what(), "no sensor_msgs/Image")) throw;
        }
      }
      ++read;
    } catch (const InvalidArgument&) {
      ++refused;
    }
  }
  spdlog::set_level(spdlog::level::info);
  std::printf("mutated bags: %d read, %d refused\n", read, refused);
  EXPECT_EQ(read + refused, 1600);
  EXPECT_GT(refused, 600);  // damage to the structure is caught
  EXPECT_GT(read, 20);      // and pixel bits are just data
}

}  // namespace
}  // namespace placedb
