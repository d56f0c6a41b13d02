#include "placedb/storage/compact_keypoint.h"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace placedb {
namespace compact_keypoint {
namespace {

constexpr double kSizeScale = 8.0;
constexpr int kAngleCodes = 360 * kAngleSteps;  // 46080
constexpr int kUnknownSide = 8189;              // a 0 x 0 stored size

uint16_t Fixed(double value, double scale) {
  return static_cast<uint16_t>(std::lround(value * scale));
}

}  // namespace

int FractionBits(cv::Size stored_size) {
  const int side = stored_size.width > 0 && stored_size.height > 0
                       ? std::max(stored_size.width, stored_size.height)
                       : kUnknownSide;
  for (int bits = kMaxFractionBits; bits >= 0; --bits) {
    if ((static_cast<int64_t>(side) + 2) << bits <= 65535) return bits;
  }
  return -1;
}

std::string WhyNotEncodable(const cv::KeyPoint& kp, int fraction_bits) {
  const float max = MaxPosition(fraction_bits);
  if (!(kp.pt.x >= -kPositionBias && kp.pt.x <= max && kp.pt.y >= -kPositionBias &&
        kp.pt.y <= max)) {
    return "a keypoint position outside [-1, " + std::to_string(max) +
           "] px (what its stored image's compact keypoints hold)";
  }
  if (!(kp.size >= 0.0f && kp.size <= kMaxSize)) return "a keypoint size outside [0, 8191.875] px";
  if (!std::isfinite(kp.angle)) return "a keypoint angle that is not finite";
  if (kp.octave < 0 || kp.octave > 255) return "a keypoint octave outside [0, 255]";
  if (kp.class_id < -128 || kp.class_id > 127) return "a keypoint class id outside [-128, 127]";
  return "";
}

void Encode(const cv::KeyPoint& kp, int fraction_bits, char* record) {
  const double scale = static_cast<double>(1 << fraction_bits);
  const uint16_t x = Fixed(static_cast<double>(kp.pt.x) + kPositionBias, scale);
  const uint16_t y = Fixed(static_cast<double>(kp.pt.y) + kPositionBias, scale);
  const uint16_t size = Fixed(kp.size, kSizeScale);
  uint16_t angle = kNoAngle;
  if (kp.angle >= 0.0f) {
    const long code = std::lround(std::fmod(static_cast<double>(kp.angle), 360.0) * kAngleSteps);
    angle = static_cast<uint16_t>(code % kAngleCodes);
  }
  const uint8_t octave = static_cast<uint8_t>(kp.octave);
  const int8_t class_id = static_cast<int8_t>(kp.class_id);
  std::memcpy(record + 0, &x, 2);
  std::memcpy(record + 2, &y, 2);
  std::memcpy(record + 4, &size, 2);
  std::memcpy(record + 6, &angle, 2);
  std::memcpy(record + 8, &octave, 1);
  std::memcpy(record + 9, &class_id, 1);
}

bool Decode(const char* record, int fraction_bits, cv::KeyPoint* kp) {
  uint16_t x, y, size, angle;
  uint8_t octave;
  int8_t class_id;
  std::memcpy(&x, record + 0, 2);
  std::memcpy(&y, record + 2, 2);
  std::memcpy(&size, record + 4, 2);
  std::memcpy(&angle, record + 6, 2);
  std::memcpy(&octave, record + 8, 1);
  std::memcpy(&class_id, record + 9, 1);
  if (angle >= kAngleCodes && angle != kNoAngle) return false;
  // Exact in float: a code has at most 16 significant bits.
  const float step = 1.0f / static_cast<float>(1 << fraction_bits);
  kp->pt.x = static_cast<float>(x) * step - kPositionBias;
  kp->pt.y = static_cast<float>(y) * step - kPositionBias;
  kp->size = static_cast<float>(size) / static_cast<float>(kSizeScale);
  kp->angle = angle == kNoAngle ? -1.0f : static_cast<float>(angle) / kAngleSteps;
  kp->response = 0.0f;
  kp->octave = octave;
  kp->class_id = class_id;
  return true;
}

cv::KeyPoint Quantized(const cv::KeyPoint& kp, int fraction_bits) {
  char record[kRecordBytes];
  Encode(kp, fraction_bits, record);
  cv::KeyPoint out;
  Decode(record, fraction_bits, &out);
  return out;
}

}  // namespace compact_keypoint
}  // namespace placedb
