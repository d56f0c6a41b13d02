// placedb_extractor: extracts each image's features once, with the
// database's own extractor settings, and publishes them for workers started
// with --input features (which then only match).
#include <image_transport/image_transport.h>
#include <placedb_msgs/Features.h>
#include <ros/ros.h>

#include "placedb/cli/flags.h"
#include "placedb/dataset/bag/image_message.h"
#include "placedb/ros/messages.h"
#include "placedb/ros/node_common.h"

int main(int argc, char** argv) {
  CLI::App app{"placedb_extractor: publishes the features of every image for the workers",
               "placedb_extractor"};
  placedb::ros_node::AddExamples(
      app, {"placedb_extractor --db out/demo/db_tum_office --cpu 1",
            "roslaunch placedb placedb.launch db:=$PWD/out/demo/db_tum_office input:=features"});
  std::string dir;
  int cpu = -1;
  app.add_option("--db", dir, "database directory (its extractor settings are used)")->required();
  app.add_option("--cpu", cpu, "pin the process to this CPU (-1: no pinning)")
      ->capture_default_str();
  int code = 0;
  if (!placedb::ros_node::Init(
          &argc, argv, [] { return std::string("placedb_extractor"); }, app, &code))
    return code;
  return placedb::ros_node::RunNode("placedb_extractor", [&] {
    placedb::ros_node::PinToCpu(cpu);
    // The keyframe table is enough: its session has the database's extractor.
    placedb::OpenOptions table;
    table.keyframe_table = true;
    const placedb::PlaceDatabase db = placedb::PlaceDatabase::Open(dir, table);
    ros::NodeHandle nh;
    image_transport::ImageTransport it(nh);
    ros::Publisher features = nh.advertise<placedb_msgs::Features>("features", 4);
    placedb::ros_node::DropLog drops("placedb_extractor");
    image_transport::Subscriber sub =
        it.subscribe("image", 1, [&](const sensor_msgs::ImageConstPtr& m) {
          try {
            const placedb::FeatureSet f = db.Extract(placedb::ImageMessageToBgr(*m));
            features.publish(placedb::FeaturesToMessage(f, m->header.seq, m->header));
          } catch (const std::exception& e) {
            drops.Drop(placedb::ros_node::CauseOf(e.what()), e.what());
          }
        });
    ROS_INFO("placedb_extractor: %s features for %s", placedb::FeatureTypeName(db.feature_type()),
             dir.c_str());
    ros::spin();
    return 0;
  });
}
