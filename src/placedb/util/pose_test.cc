#include "placedb/util/pose.h"

#include <gtest/gtest.h>

namespace placedb {
namespace {

TEST(PoseTest, DistanceAndAngle) {
  Pose a;
  Pose b;
  b.translation = Eigen::Vector3d(3, 4, 0);
  b.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 6, Eigen::Vector3d::UnitZ()));
  EXPECT_NEAR(TranslationDistance(a, b), 5.0, 1e-12);
  EXPECT_NEAR(RotationAngleDeg(a, b), 30.0, 1e-9);
  // q and -q are the same rotation.
  Pose c = b;
  c.rotation.coeffs() *= -1.0;
  EXPECT_NEAR(RotationAngleDeg(b, c), 0.0, 1e-6);
}

}  // namespace
}  // namespace placedb
