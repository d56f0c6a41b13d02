// Feature extraction behind one interface, chosen by a factory from options.
#pragma once

#include <memory>
#include <opencv2/core.hpp>
#include <string>

#include "placedb/feature/options.h"
#include "placedb/feature/surf/surf.h"
#include "placedb/feature/types.h"

namespace placedb {

// Bytes per descriptor row the options produce: 32 (ORB), 256 or 512 (SURF).
int DescriptorBytes(const ExtractorOptions& options);
// Values per whole-image row the options produce: width x height, 0 when
// the channel is off.
int WholeImageDims(const ExtractorOptions& options);

class FeatureExtractor {
 public:
  virtual ~FeatureExtractor() = default;

  // Keypoints and descriptors of an 8-bit gray or BGR image. Images too small
  // to hold a feature give an empty set, never an error. With
  // options.whole_image.enabled, also the image's whole-image descriptor
  // (FeatureSet::whole_image, of the image as given: before small frames
  // are upscaled; empty for an empty image).
  virtual FeatureSet Extract(const cv::Mat& image) const = 0;
  virtual FeatureType type() const = 0;

  // The concrete extractor for `options.type`.
  static std::unique_ptr<FeatureExtractor> Create(const ExtractorOptions& options);
};

}  // namespace placedb
