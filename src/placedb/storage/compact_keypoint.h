// The compact keypoint of keyframe file format 3: 10 bytes where a
// cv::KeyPoint takes 28, keeping what the stages use at a documented
// precision.
//
//   u16 x, u16 y   (position + 1 px) x 2^b: b fraction bits, set by the
//                  keyframe's stored image (FractionBits): 8 (1/256 px) for
//                  sides up to 253 px, 6 (1/64 px) up to 1021 px, 3 (1/8 px)
//                  up to 8189 px, 0 up to 65533 px; a position lies in
//                  [-1, 65535 / 2^b - 1]
//   u16 size       size in 1/8 px: [0, 8191.875]
//   u16 angle      angle in 1/128 degree, [0, 46080); 0xFFFF: no angle (-1)
//   u8 octave      [0, 255]
//   i8 class_id    [-128, 127] (SURF: the sign of the Laplacian, +1 / -1)
//
// The response is not kept (it reads 0): no stage after extraction uses it.
// A database holds its keypoints quantized from the moment they are added
// (Database::AddKeyframe keeps Quantized(kp, bits)), so a database answers
// the same before and after a save and a load. Quantizing is idempotent; it
// moves a position by at most half a step (1/512 px on a 160 x 120 stored
// image, 1/128 px on 640 x 480), a size by 1/16 px and an angle by 1/256
// degree; verification's inlier threshold is pixels.
#pragma once

#include <cstddef>
#include <cstdint>
#include <opencv2/core/types.hpp>
#include <string>

namespace placedb {
namespace compact_keypoint {

constexpr size_t kRecordBytes = 10;
// What the section's preamble says about positions: fraction bits from the
// stored size (FractionBits).
constexpr uint32_t kPositionScheme = 1;
constexpr int kMaxFractionBits = 8;
constexpr float kPositionBias = 1.0f;        // -1 px (the keypoint tolerance) maps to 0
constexpr float kMaxSize = 65535.0f / 8.0f;  // 8191.875
constexpr int kAngleSteps = 128;             // per degree
constexpr uint16_t kNoAngle = 0xFFFF;

// The fraction bits of positions in a stored image of `stored_size`: the
// most, up to 8, with (side + 2) x 2^b <= 65535 for the larger side (a 0 x 0
// size, unknown, counts as 8189 px: 3 bits); -1 when the side is larger
// than 65533 px.
int FractionBits(cv::Size stored_size);
// The largest position of `fraction_bits`.
inline float MaxPosition(int fraction_bits) {
  return 65535.0f / static_cast<float>(1 << fraction_bits) - kPositionBias;
}

// Why `kp` cannot be encoded with `fraction_bits` (>= 0), or "": a position
// outside [-1, MaxPosition(bits)], a size outside [0, 8191.875], an angle
// that is not finite, an octave outside [0, 255] or a class id outside
// [-128, 127].
std::string WhyNotEncodable(const cv::KeyPoint& kp, int fraction_bits);
// The record of an encodable keypoint.
void Encode(const cv::KeyPoint& kp, int fraction_bits, char* record);
// The keypoint of a record. False (and *kp untouched) for a record no
// encoder writes: an angle code in [46080, 0xFFFF).
bool Decode(const char* record, int fraction_bits, cv::KeyPoint* kp);
// Decode(Encode(kp)): what a database keeps of an encodable keypoint.
cv::KeyPoint Quantized(const cv::KeyPoint& kp, int fraction_bits);

}  // namespace compact_keypoint
}  // namespace placedb
