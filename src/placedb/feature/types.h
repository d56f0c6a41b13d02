// Feature types. Descriptors carry their type: ORB's are 32-byte binary
// strings compared by Hamming distance, SURF's 64 or 128 floats compared by
// L2 distance. Mixing them is an error.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace placedb {

enum class FeatureType : uint32_t { kOrb = 1, kSurf = 2 };

// "orb" / "surf".
const char* FeatureTypeName(FeatureType type);
// Parses "orb" or "surf" (case-insensitive); throws InvalidArgument.
FeatureType ParseFeatureType(const std::string& name);

// Keypoints and their descriptors (one row each) from one image.
struct FeatureSet {
  FeatureType type = FeatureType::kOrb;
  std::vector<cv::KeyPoint> keypoints;
  // ORB: CV_8U, 32 columns. SURF: CV_32F, 64 or 128 columns.
  cv::Mat descriptors;
  // The whole-image descriptor (feature/whole_image.h) of the image the
  // features came from: 1 x D CV_8S, empty when not computed.
  cv::Mat whole_image;

  size_t size() const { return keypoints.size(); }
  bool empty() const { return keypoints.empty(); }
};

// Throws InvalidArgument unless `a` and `b` can be compared: same type,
// same descriptor width and element type. `what` names the context.
void CheckCompatibleDescriptors(FeatureType a_type, const cv::Mat& a, FeatureType b_type,
                                const cv::Mat& b, const std::string& what);

}  // namespace placedb
