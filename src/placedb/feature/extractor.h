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
// Values per whole-image row the options produce: width x height for the
// thumbnail, hog_dims for HOG, 0 when the channel is off.
int WholeImageDims(const ExtractorOptions& options);

class WholeImageModel;

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
  // The whole-image row of `image` alone (what Extract puts in
  // FeatureSet::whole_image); empty when the channel is off.
  virtual cv::Mat WholeImage(const cv::Mat& image) const { return cv::Mat(); }

  // The concrete extractor for `options.type`. With WholeImageKind::kHog the
  // whole-image row is `model`'s projection (a CV_8S row of hog_dims); without
  // a model it is the raw HOG row (CV_8U, feature/whole_image_model.h) that a
  // build fits its model on. `model` must outlive the extractor.
  static std::unique_ptr<FeatureExtractor> Create(const ExtractorOptions& options,
                                                  std::shared_ptr<const WholeImageModel> model =
                                                      nullptr);
};

}  // namespace placedb
