// placedb_feed: publishes frames (an image folder or list, a TUM folder, or a
// bag) on the image topic, at a rate or as fast as the system answers. Each
// frame's header carries its sequence number (seq, from 0) and the source's
// timestamp; the same numbers go first on the topic `frames`, for the
// voter's deadlines, with the feed's run id as frame_id: a run id the voter
// has not seen starts a new run there. (roscpp numbers header.seq per
// publisher, one message per frame on each: the image's seq is the frame's
// number.) At its end the feed reports its run: frames sent, answered
// (complete, partial) and never answered.
#include <image_transport/image_transport.h>
#include <placedb_msgs/Answer.h>
#include <ros/callback_queue.h>
#include <ros/ros.h>
#include <sensor_msgs/CompressedImage.h>
#include <std_msgs/Header.h>

#include <fmt/format.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <set>

#include "placedb/cli/flags.h"
#include "placedb/dataset/bag/image_message.h"
#include "placedb/ros/node_common.h"

int main(int argc, char** argv) {
  namespace cli = placedb::cli;
  CLI::App app{"placedb_feed: publishes frames for the placedb workers", "placedb_feed"};
  placedb::ros_node::AddExamples(
      app, {"placedb_feed --tum data/tum_fr3_office_32 --wait-for 3",
            "placedb_feed --images data/rtabmap_loop/images --rate 10 --log-file feed.jsonl"});
  cli::SourceArgs source;
  double rate = 0.0;
  double answer_timeout_ms = 2000.0;
  int wait_for = 0;
  int loops = 1;
  std::string compress, frame_id = "camera", log_file, run_id;
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
                 "append each published frame (seq, wall time) as a JSON line, and the run's "
                 "report last");
  app.add_option("--run-id", run_id,
                 "this run's id, the frame_id of the announcements on frames (default: made up, "
                 "16 hex digits); a run id the voter has not seen resets it");
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
    if (run_id.empty()) {
      std::random_device random;
      run_id = fmt::format("{:08x}{:08x}", random(), random());
    }
    if (run_id.size() > 256) throw placedb::InvalidArgument("`run_id` is longer than 256 bytes");
    // This run's answers (the voter's answers carry the run id of the frames'
    // announcements; answers of other runs, such as the latched last one of
    // the run before, are not this run's). A frame counts once.
    std::set<uint64_t> answered;
    uint64_t complete = 0, partial = 0;
    ros::Subscriber answers = nh.subscribe<placedb_msgs::Answer>(
        "answers", 100,
        [&](const placedb_msgs::AnswerConstPtr& a) {
          if (a->run_id != run_id || !answered.insert(a->frame_seq).second) return;
          ++(a->complete ? complete : partial);
        },
        ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
    std::ofstream log;
    if (!log_file.empty()) {
      log.open(log_file, std::ios::app);
      if (!log.good()) throw placedb::IoError("cannot write " + log_file);
    }
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
    ROS_INFO("placedb_feed: run %s: %zu frames from %s, %s", run_id.c_str(), frames.size(),
             source.Describe().c_str(),
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
        std_msgs::Header announcement = header;
        announcement.frame_id = run_id;
        announce.publish(announcement);
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
                                {"run", run_id},
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
          while (ros::ok() && !answered.count(seq) && ros::WallTime::now() < until) {
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
    while (ros::ok() && answered.size() < seq && ros::WallTime::now() < until) {
      ros::spinOnce();
      ros::WallDuration(0.001).sleep();
    }
    // The run's report: one line, and the log file's last line.
    std::vector<uint64_t> never;
    for (uint64_t i = 0; i < seq; ++i) {
      if (!answered.count(i)) never.push_back(i);
    }
    std::string line = fmt::format(
        "placedb_feed: run {}: {} frames sent, {} answered ({} complete, {} partial), {} never "
        "answered",
        run_id, seq, seq - never.size(), complete, partial, never.size());
    if (!never.empty()) {
      line += " (frames";
      for (size_t i = 0; i < never.size() && i < 20; ++i) line += " " + std::to_string(never[i]);
      line += never.size() > 20 ? " ...)" : ")";
    }
    ROS_INFO("%s", line.c_str());
    if (log.is_open()) {
      log << nlohmann::json{{"run", run_id},
                            {"frames_sent", seq},
                            {"answered", seq - never.size()},
                            {"complete", complete},
                            {"partial", partial},
                            {"never_answered", never.size()},
                            {"never_answered_frames", never}}
                 .dump()
          << "\n"
          << std::flush;
    }
    return 0;
  });
}
