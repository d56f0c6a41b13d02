#include "placedb/eval/ground_truth.h"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "placedb/util/error.h"

namespace placedb {
namespace {

Frame FrameAt(int id, double x, double yaw_deg) {
  Frame f;
  f.id = id;
  Pose p;
  p.translation = Eigen::Vector3d(x, 0, 0);
  p.rotation =
      Eigen::Quaterniond(Eigen::AngleAxisd(yaw_deg * M_PI / 180, Eigen::Vector3d::UnitY()));
  f.pose = p;
  return f;
}

Keyframe KeyframeAt(int id, double x, double yaw_deg) {
  Keyframe k;
  k.id = id;
  k.pose = FrameAt(id, x, yaw_deg).pose;
  return k;
}

TEST(GroundTruthTest, MatchList) {
  const GroundTruth truth = GroundTruth::FromMatchList({{41, {3, 1, 2}}, {42, {}}});
  Frame q41;
  q41.id = 41;
  Frame q43;
  q43.id = 43;
  Keyframe k2;
  k2.id = 2;
  Keyframe k5;
  k5.id = 5;
  EXPECT_TRUE(truth.HasTruth(q41));
  EXPECT_FALSE(truth.HasTruth(q43));
  EXPECT_TRUE(truth.IsCorrect(q41, k2));
  EXPECT_FALSE(truth.IsCorrect(q41, k5));
  EXPECT_FALSE(truth.IsCorrect(q43, k2));
}

TEST(GroundTruthTest, PoseThresholds) {
  PoseThresholds t;  // 0.5 m, 30 deg
  const GroundTruth truth = GroundTruth::FromPoses(t);
  const Frame q = FrameAt(1, 0.0, 0.0);
  EXPECT_TRUE(truth.IsCorrect(q, KeyframeAt(2, 0.49, 29.0)));
  EXPECT_FALSE(truth.IsCorrect(q, KeyframeAt(3, 0.51, 0.0)));   // too far
  EXPECT_FALSE(truth.IsCorrect(q, KeyframeAt(4, 0.10, 31.0)));  // looks elsewhere
  Keyframe no_pose;
  no_pose.id = 5;
  EXPECT_FALSE(truth.IsCorrect(q, no_pose));
  Frame pose_less;
  EXPECT_FALSE(truth.HasTruth(pose_less));
  PoseThresholds bad;
  bad.max_angle_deg = 0;
  EXPECT_THROW(GroundTruth::FromPoses(bad), InvalidArgument);
}

}  // namespace
}  // namespace placedb
