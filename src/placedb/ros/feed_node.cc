// placedb_feed: publishes frames (an image folder or list, a TUM folder, or a
// bag) on the image topic, at a rate or as fast as the system answers. Each
// frame's header carries its sequence number (seq, from 0) and the source's
// timestamp; the same header goes first on the topic `frames`, for the
// voter's deadlines. (roscpp numbers header.seq per publisher, one message
// per frame on each: the image's seq is the frame's number.)
#include <image_transport/image_transport.h>
#include <placedb_msgs/Answer.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/CompressedImage.h>
#include <std_msgs/Header.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "placedb/cli/flags.h"
#include "placedb/dataset/bag/image_message.h"
#include "placedb/ros/node_common.h"

int main(int argc, char** argv) {
  namespace cli = placedb::cli;
  CLI::App app{"placedb_feed: publishes frames for the placedb workers"};
  cli::SourceArgs source;
  double rate = 0.0;
  double answer_timeout_ms = 2000.0;
  int wait_for = 0;
  int loops = 1;
  std::string compress, frame_id = "camera", log_file;
  source.Add(&app);
  app.add_option("--rate", rate,
                 "frames per second; 0: each frame when the previous one is "
                 "answered (or answer-timeout-ms passed) [0, 1000]")
      ->capture_default_str();
  app.add_option("--answer-timeout-ms", answer_timeout_ms,
                 "with --rate 0: publish the next frame after this long without an answer")
      ->capture_default_str();
  app.add_option("--wait-for", wait_for,
                 "wait until this many nodes subscribe to the image (or compressed) topic, and "
                 "one (the voter) to frames")
      ->capture_default_str();
  app.add_option("--loops", loops, "publish the sequence this many times [1, 1000000]")
      ->capture_default_str();
  app.add_option("--compress", compress, "also publish image/compressed as jpeg or png")
      ->check(CLI::IsMember({"jpeg", "png"}));
  app.add_option("--frame-id", frame_id, "frame_id of the images")->capture_default_str();
  app.add_option("--log-file", log_file,
                 "append each published frame (seq, wall time) as a JSON line");
  int code = 0;
  if (!placedb::ros_node::Init(
          &argc, argv, [] { return std::string("placedb_feed"); }, app, &code))
    return code;
  return placedb::ros_node::RunNode("placedb_feed", [&] {
    if (!(rate >= 0 && rate <= 1000)) throw placedb::InvalidArgument("`rate` must be in [0, 1000]");
    if (!(answer_timeout_ms > 0 && answer_timeout_ms <= 600000))
      throw placedb::InvalidArgument("`answer_timeout_ms` must be in (0, 600000]");
    if (loops < 1 || loops > 1000000) throw placedb::InvalidArgument("`loops` must be in [1, 1000000]");
    if (wait_for < 0 || wait_for > 4096) throw placedb::InvalidArgument("`wait_for` must be in [0, 4096]");
    const std::vector<placedb::Frame> frames = source.Read();
    ros::NodeHandle nh;
    image_transport::ImageTransport it(nh);
    image_transport::Publisher images = it.advertise("image", 4);
    ros::Publisher compressed;
    if (!compress.empty())
      compressed = nh.advertise<sensor_msgs::CompressedImage>("image/compressed", 4);
    ros::Publisher announce = nh.advertise<std_msgs::Header>("frames", 100);
    uint64_t answered = 0;
    bool have_answer = false;
    ros::Subscriber answers = nh.subscribe<placedb_msgs::Answer>(
        "answers", 100,
        [&](const placedb_msgs::AnswerConstPtr& a) {
          answered = std::max(answered, a->frame_seq);
          have_answer = true;
        },
        ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
    std::ofstream log;
    if (!log_file.empty()) log.open(log_file, std::ios::app);
    // Subscribers first, or the first frames go nowhere: the workers (on the
    // image or compressed topic) and the voter (on frames).
    while (
        ros::ok() && wait_for > 0 &&
        (static_cast<int>(std::max(images.getNumSubscribers(),
                                   compressed ? compressed.getNumSubscribers() : 0)) < wait_for ||
         announce.getNumSubscribers() < 1)) {
      ros::WallDuration(0.01).sleep();
      ros::spinOnce();
    }
    ROS_INFO("placedb_feed: %zu frames from %s, %s", frames.size(), source.Describe().c_str(),
             rate > 0 ? (std::to_string(rate) + " per second").c_str() : "paced by the answers");
    ros::WallDuration(0.2).sleep();  // let subscriptions settle
    uint64_t seq = 0;
    ros::WallRate pace(rate > 0 ? rate : 1.0);
    for (int loop = 0; loop < loops && ros::ok(); ++loop) {
      for (const placedb::Frame& f : frames) {
        if (!ros::ok()) break;
        const cv::Mat image = placedb::LoadFrameImage(f);
        if (image.empty()) {
          ROS_WARN("placedb_feed: skipped unreadable image %s", f.image_path.c_str());
          continue;
        }
        // The frame's number (from 0) is how the workers and the voter know
        // it. roscpp numbers header.seq per publisher, one message per frame
        // on each, for messages that contain a header (the image, the
        // compressed image); the announcement is a bare std_msgs/Header,
        // which roscpp leaves as it is, so its seq is set here.
        std_msgs::Header header;
        header.stamp = f.timestamp >= 0 ? ros::Time(f.timestamp) : ros::Time::now();
        header.frame_id = frame_id;
        header.seq = static_cast<uint32_t>(seq);
        announce.publish(header);
        images.publish(placedb::BgrToImageMessage(image, header));
        if (compressed) {
          sensor_msgs::CompressedImage c;
          c.header = header;
          c.format = compress;
          cv::imencode(compress == "jpeg" ? ".jpg" : ".png", image, c.data);
          compressed.publish(c);
        }
        if (log.is_open()) {
          log << nlohmann::json{{"frame_seq", seq},
                                {"frame_id", f.id},
                                {"wall_ms", placedb::ros_node::WallMs()}}
                     .dump()
              << "\n"
              << std::flush;
        }
        if (rate > 0) {
          ros::spinOnce();
          pace.sleep();
        } else {
          const ros::WallTime until =
              ros::WallTime::now() + ros::WallDuration(answer_timeout_ms / 1000.0);
          while (ros::ok() && !(have_answer && answered >= seq) && ros::WallTime::now() < until) {
            ros::spinOnce();
            ros::WallDuration(0.0002).sleep();
          }
        }
        ++seq;
      }
    }
    // Give the last frames' answers a moment before the feed goes away.
    const ros::WallTime until =
        ros::WallTime::now() + ros::WallDuration(answer_timeout_ms / 1000.0);
    while (ros::ok() && seq > 0 && !(have_answer && answered >= seq - 1) &&
           ros::WallTime::now() < until) {
      ros::spinOnce();
      ros::WallDuration(0.001).sleep();
    }
    ROS_INFO("placedb_feed: published %lu frames", static_cast<unsigned long>(seq));
    return 0;
  });
}
