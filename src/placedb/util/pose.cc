#include "placedb/util/pose.h"

#include <algorithm>
#include <cmath>

namespace placedb {

double TranslationDistance(const Pose& a, const Pose& b) {
  return (a.translation - b.translation).norm();
}

double RotationAngleDeg(const Pose& a, const Pose& b) {
  // |<qa, qb>| = cos(theta / 2) for unit quaternions; abs() folds q ~ -q.
  const double dot = std::abs(a.rotation.normalized().dot(b.rotation.normalized()));
  return 2.0 * std::acos(std::min(1.0, dot)) * 180.0 / M_PI;
}

}  // namespace placedb
