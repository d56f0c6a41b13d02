// A rigid camera pose (camera-to-world, as TUM's ground truth: translation in
// metres and a unit quaternion) and the distances used to judge matches.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace placedb {

struct Pose {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();         // metres
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  // unit quaternion
};

// Euclidean distance between the two camera centres, metres.
double TranslationDistance(const Pose& a, const Pose& b);

// Angle of the relative rotation between the two poses, degrees in [0, 180].
double RotationAngleDeg(const Pose& a, const Pose& b);

}  // namespace placedb
