#include "placedb/feature/extractor.h"

#include <algorithm>
#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "placedb/dataset/frame.h"
#include "placedb/feature/whole_image.h"
#include "placedb/feature/whole_image_model.h"
#include "placedb/image/chromaticity.h"
#include "placedb/util/check.h"
#include "placedb/util/options.h"

namespace placedb {

int DescriptorBytes(const ExtractorOptions& options) {
  if (options.type == FeatureType::kOrb) return 32;
  return (options.surf.extended ? 128 : 64) * static_cast<int>(sizeof(float));
}

int WholeImageDims(const ExtractorOptions& options) {
  const WholeImageOptions& w = options.whole_image;
  if (!w.enabled) return 0;
  return w.kind == WholeImageKind::kHog ? w.hog_dims : w.width * w.height;
}

namespace {

class OrbExtractor : public FeatureExtractor {
 public:
  explicit OrbExtractor(const OrbOptions& options)
      : edge_threshold_(options.edge_threshold),
        orb_(cv::ORB::create(options.max_features, static_cast<float>(options.scale_factor),
                             options.num_levels, options.edge_threshold, 0, 2,
                             cv::ORB::HARRIS_SCORE, options.patch_size, options.fast_threshold)) {}

  FeatureSet Extract(const cv::Mat& image) const override {
    FeatureSet set;
    set.type = FeatureType::kOrb;
    set.descriptors = cv::Mat(0, 32, CV_8U);
    const cv::Mat gray = ToGray(image);
    // ORB keeps no keypoint within edge_threshold of the border (and OpenCV
    // fails on images smaller than that): such images have no features.
    if (gray.cols <= 2 * edge_threshold_ || gray.rows <= 2 * edge_threshold_) return set;
    cv::Mat descriptors;
    orb_->detectAndCompute(gray, cv::noArray(), set.keypoints, descriptors);
    if (!set.keypoints.empty()) set.descriptors = descriptors;
    return set;
  }
  FeatureType type() const override { return FeatureType::kOrb; }

 private:
  int edge_threshold_;
  cv::Ptr<cv::ORB> orb_;
};

class SurfExtractor : public FeatureExtractor {
 public:
  explicit SurfExtractor(const SurfOptions& options) : options_(options) {}

  FeatureSet Extract(const cv::Mat& image) const override {
    FeatureSet set;
    set.type = FeatureType::kSurf;
    set.descriptors = cv::Mat(0, options_.extended ? 128 : 64, CV_32F);
    const cv::Mat gray = ToGray(image);
    if (gray.empty()) return set;
    cv::Mat descriptors;
    DetectAndComputeSurf(gray, options_, &set.keypoints, &descriptors);
    if (!set.keypoints.empty()) set.descriptors = descriptors;
    return set;
  }
  FeatureType type() const override { return FeatureType::kSurf; }

 private:
  SurfOptions options_;
};

// Extracts small images upscaled, then maps the keypoints back: OpenCV's
// resize puts destination pixel centre x' at (x + 0.5) f - 0.5. Tiny images
// (thumbnails, a few pixels) are not blown up beyond kMaxUpscale.
constexpr double kMaxUpscale = 4.0;
constexpr double kSmallUpscale = 2.0;  // upscaled_fast_threshold from this factor on
class UpscalingExtractor : public FeatureExtractor {
 public:
  // `small`: the extractor of upscaled images (nullptr: `inner`).
  UpscalingExtractor(std::unique_ptr<FeatureExtractor> inner,
                     std::unique_ptr<FeatureExtractor> small, int upscale_below)
      : inner_(std::move(inner)), small_(std::move(small)), upscale_below_(upscale_below) {}

  FeatureSet Extract(const cv::Mat& image) const override {
    const int shorter = std::min(image.cols, image.rows);
    if (image.empty() || shorter >= upscale_below_) return inner_->Extract(image);
    double f = std::min(static_cast<double>(upscale_below_) / shorter, kMaxUpscale);
    // A long thin image is not blown up past the default image bound
    // (kDefaultMaxImagePixels): 60 x 666 666 pixels would become 640 megapixels.
    const double pixels = static_cast<double>(image.cols) * image.rows;
    if (pixels * f * f > static_cast<double>(kDefaultMaxImagePixels))
      f = std::sqrt(static_cast<double>(kDefaultMaxImagePixels) / pixels);
    if (f <= 1.0) return inner_->Extract(image);
    cv::Mat big;
    cv::resize(image, big,
               cv::Size(static_cast<int>(std::lround(image.cols * f)),
                        static_cast<int>(std::lround(image.rows * f))),
               0, 0, cv::INTER_LINEAR);
    // The lower FAST threshold only where the upscaling is at least 2x (tiny
    // frames): a stored image of 1/4 the area, upscaled 1.25x, matched
    // full-size queries worse with it (data/rtabmap_loop, ORB 1/4: 41 of 44
    // right instead of 42).
    FeatureSet set = small_ && f >= kSmallUpscale ? small_->Extract(big) : inner_->Extract(big);
    const double fx = static_cast<double>(big.cols) / image.cols;
    const double fy = static_cast<double>(big.rows) / image.rows;
    for (cv::KeyPoint& kp : set.keypoints) {
      kp.pt.x = static_cast<float>((kp.pt.x + 0.5) / fx - 0.5);
      kp.pt.y = static_cast<float>((kp.pt.y + 0.5) / fy - 0.5);
      kp.size = static_cast<float>(kp.size / f);
    }
    return set;
  }
  FeatureType type() const override { return inner_->type(); }

 private:
  std::unique_ptr<FeatureExtractor> inner_, small_;
  int upscale_below_;
};

// Extracts local features from the grey image contrast-equalised by CLAHE.
class ContrastExtractor : public FeatureExtractor {
 public:
  explicit ContrastExtractor(std::unique_ptr<FeatureExtractor> inner) : inner_(std::move(inner)) {}

  FeatureSet Extract(const cv::Mat& image) const override {
    if (image.empty()) return inner_->Extract(image);
    cv::Mat equalised;
    // One CLAHE a call: its buffers make a shared one unsafe across threads.
    cv::createCLAHE(2.0, cv::Size(8, 8))->apply(ToGray(image), equalised);
    return inner_->Extract(equalised);
  }
  FeatureType type() const override { return inner_->type(); }

 private:
  std::unique_ptr<FeatureExtractor> inner_;
};

// Adds the whole-image descriptor of the image as given (before any
// upscaling) to the inner extractor's features.
class WholeImageExtractor : public FeatureExtractor {
 public:
  WholeImageExtractor(std::unique_ptr<FeatureExtractor> inner, const WholeImageOptions& options,
                      std::shared_ptr<const WholeImageModel> model)
      : inner_(std::move(inner)), options_(options), model_(std::move(model)) {}

  FeatureSet Extract(const cv::Mat& image) const override {
    FeatureSet set = inner_->Extract(image);
    set.whole_image = WholeImage(image);
    return set;
  }
  FeatureType type() const override { return inner_->type(); }
  cv::Mat WholeImage(const cv::Mat& image) const override {
    if (image.empty()) return cv::Mat();
    if (options_.kind == WholeImageKind::kThumbnail)
      return ComputeWholeImageDescriptor(image, options_);
    if (model_) return model_->Describe(image);
    // The raw rows a build fits its model on; height 0: the frame's aspect.
    const int height = options_.hog_height != 0 ? options_.hog_height
                                                : HogHeightForFrame(options_.hog_width, image.size());
    return ComputeHogRaw(image, options_.hog_width, height);
  }

 private:
  std::unique_ptr<FeatureExtractor> inner_;
  WholeImageOptions options_;
  std::shared_ptr<const WholeImageModel> model_;
};

}  // namespace

std::unique_ptr<FeatureExtractor> FeatureExtractor::Create(
    const ExtractorOptions& options, std::shared_ptr<const WholeImageModel> model) {
  PLACEDB_CHECK_OPTIONS(options);
  const WholeImageOptions& w = options.whole_image;
  if (w.enabled && w.kind == WholeImageKind::kHog) {
    if (model && w.hog_height == 0) {
      PLACEDB_THROW_INVALID("the HOG whole-image channel's model needs its thumbnail height "
                            "(`whole_image_hog_height`, set from the map's frames by a build)");
    }
    if (model && (model->width() != w.hog_width || model->height() != w.hog_height ||
                  model->output_dims() != w.hog_dims)) {
      PLACEDB_THROW_INVALID("a whole-image model of ", model->width(), " x ", model->height(),
                            " thumbnails and ", model->output_dims(), " values for options of ",
                            w.hog_width, " x ", w.hog_height, " and ", w.hog_dims);
    }
  }
  std::unique_ptr<FeatureExtractor> extractor;
  switch (options.type) {
    case FeatureType::kOrb:
      extractor = std::make_unique<OrbExtractor>(options.orb);
      break;
    case FeatureType::kSurf:
      extractor = std::make_unique<SurfExtractor>(options.surf);
      break;
  }
  if (!extractor) PLACEDB_THROW_INVALID("unknown feature type");
  if (options.upscale_below > 0) {
    std::unique_ptr<FeatureExtractor> small;
    if (options.type == FeatureType::kOrb && options.upscaled_fast_threshold > 0 &&
        options.upscaled_fast_threshold != options.orb.fast_threshold) {
      OrbOptions orb = options.orb;
      orb.fast_threshold = options.upscaled_fast_threshold;
      small = std::make_unique<OrbExtractor>(orb);
    }
    extractor = std::make_unique<UpscalingExtractor>(std::move(extractor), std::move(small),
                                                     options.upscale_below);
  }
  if (options.clahe) extractor = std::make_unique<ContrastExtractor>(std::move(extractor));
  if (options.whole_image.enabled) {
    extractor = std::make_unique<WholeImageExtractor>(std::move(extractor), options.whole_image,
                                                      std::move(model));
  }
  return extractor;
}

}  // namespace placedb
