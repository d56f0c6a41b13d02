// What a database keeps of one training frame, without its features: the
// keyframe record (part of the public face, placedb/placedb.h).
#pragma once

#include <cstdint>
#include <opencv2/core/types.hpp>
#include <optional>
#include <string>

#include "placedb/util/pose.h"

namespace placedb {

struct Keyframe {
  int32_t id = 0;             // the source frame's id, >= 1
  double timestamp = -1.0;    // seconds, -1 when unknown
  std::optional<Pose> pose;   // ground-truth / map pose, when known
  cv::Rect crop;              // kept region, in the original image
  int32_t crop_channel = -1;  // winning chromaticity channel, -1: whole image
  cv::Size original_size;     // of the source image (0 x 0: unknown)
  cv::Size stored_size;       // of the stored (cropped, resized) image
  double scale = 1.0;         // stored = (original - crop.tl()) * scale
  std::string source;         // path of the source image
  std::string image_file;     // stored PNG relative to the database dir ("" if none)
  // What the source was when the keyframe was made (SourceHash,
  // dataset/frame.h): XXH3-64 of the image file's bytes (of the decoded
  // pixels for frames without a file, from a bag); 0 when not recorded
  // (keyframes saved by an earlier placedb, or added from features).
  // `placedb add --skip-existing` knows a frame it already holds by source
  // path and this hash.
  uint64_t source_hash = 0;

  // Maps a point of the stored image back to the original image.
  cv::Point2f ToOriginal(const cv::Point2f& stored) const {
    return {static_cast<float>(stored.x / scale + crop.x),
            static_cast<float>(stored.y / scale + crop.y)};
  }
};

}  // namespace placedb
