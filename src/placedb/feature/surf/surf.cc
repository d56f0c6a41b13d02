#include "placedb/feature/surf/surf.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "placedb/feature/surf/fast_hessian.h"
#include "placedb/feature/surf/integral_image.h"
#include "placedb/feature/surf/surf_descriptor.h"
#include "placedb/util/check.h"

namespace placedb {
namespace {

using surf_internal::IntegralImage;

constexpr int kMaxOctaves = 8;
constexpr int kMaxOctaveLayers = 8;

int DescriptorDim(const SurfOptions& options) { return options.extended ? 128 : 64; }

// Grey 8-bit view or copy of the input; throws on unsupported types.
cv::Mat ToGray(const cv::Mat& image) {
  if (image.empty()) return cv::Mat();
  switch (image.type()) {
    case CV_8UC1:
      return image;
    case CV_8UC3: {
      cv::Mat gray;
      cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
      return gray;
    }
    case CV_8UC4: {
      cv::Mat gray;
      cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
      return gray;
    }
    default:
      PLACEDB_THROW_INVALID("SURF needs an 8-bit grey, BGR or BGRA image (got ",
                            cv::typeToString(image.type()), ")");
  }
}

// Keeps the `max_features` strongest keypoints (ties broken by position so
// the result does not depend on the sort's internals).
void KeepStrongest(int max_features, std::vector<cv::KeyPoint>* keypoints) {
  if (max_features <= 0 || static_cast<int>(keypoints->size()) <= max_features) return;
  auto stronger = [](const cv::KeyPoint& a, const cv::KeyPoint& b) {
    if (a.response != b.response) return a.response > b.response;
    if (a.pt.y != b.pt.y) return a.pt.y < b.pt.y;
    if (a.pt.x != b.pt.x) return a.pt.x < b.pt.x;
    return a.size < b.size;
  };
  std::nth_element(keypoints->begin(), keypoints->begin() + max_features, keypoints->end(),
                   stronger);
  keypoints->resize(max_features);
  std::sort(keypoints->begin(), keypoints->end(), stronger);
}

// Orientation (unless upright) and descriptors of *keypoints.
void Describe(const IntegralImage& ii, const SurfOptions& options,
              std::vector<cv::KeyPoint>* keypoints, cv::Mat* descriptors) {
  const int dim = DescriptorDim(options);
  if (descriptors != nullptr) {
    descriptors->create(static_cast<int>(keypoints->size()), dim, CV_32F);
  }
  for (size_t k = 0; k < keypoints->size(); ++k) {
    cv::KeyPoint& kp = (*keypoints)[k];
    kp.angle = options.upright ? 0.f : surf_internal::ComputeOrientation(ii, kp);
    if (descriptors != nullptr) {
      surf_internal::ComputeDescriptor(ii, kp, options.upright, options.extended,
                                       descriptors->ptr<float>(static_cast<int>(k)));
    }
  }
}

// The whole pipeline. mask: empty or CV_8UC1 of the image's size.
void Run(const cv::Mat& image, const cv::Mat& mask, const SurfOptions& options, bool use_provided,
         std::vector<cv::KeyPoint>* keypoints, cv::Mat* descriptors) {
  PLACEDB_CHECK_OPTIONS(options);
  PLACEDB_CHECK(keypoints != nullptr);
  const cv::Mat gray = ToGray(image);
  // A mask comes from a caller of SurfFeature2D (OpenCV's interface).
  if (!mask.empty()) {
    if (mask.type() != CV_8UC1) {
      PLACEDB_THROW_INVALID("a SURF mask must be CV_8UC1 (got ", cv::typeToString(mask.type()),
                            ")");
    }
    if (mask.size() != image.size()) {
      PLACEDB_THROW_INVALID("a SURF mask must have the image's size ", image.size(), " (got ",
                            mask.size(), ")");
    }
  }
  if (use_provided) {
    for (const cv::KeyPoint& kp : *keypoints) {
      if (!(std::isfinite(kp.pt.x) && std::isfinite(kp.pt.y) && std::isfinite(kp.size) &&
            kp.size > 0.f)) {
        PLACEDB_THROW_INVALID("a keypoint to describe needs a finite position and size > 0 (got ",
                              kp.pt, ", size ", kp.size, ")");
      }
    }
  } else {
    keypoints->clear();
  }
  const IntegralImage ii(gray);
  if (!use_provided) {
    surf_internal::DetectFastHessian(ii, options.hessian_threshold, options.num_octaves,
                                     options.num_octave_layers, keypoints);
    if (!mask.empty()) cv::KeyPointsFilter::runByPixelsMask(*keypoints, mask);
    KeepStrongest(options.max_features, keypoints);
  }
  Describe(ii, options, keypoints, descriptors);
}

}  // namespace

void DetectAndComputeSurf(const cv::Mat& image, const SurfOptions& options,
                          std::vector<cv::KeyPoint>* keypoints, cv::Mat* descriptors) {
  Run(image, cv::Mat(), options, /*use_provided=*/false, keypoints, descriptors);
}

void DetectSurf(const cv::Mat& image, const SurfOptions& options,
                std::vector<cv::KeyPoint>* keypoints) {
  Run(image, cv::Mat(), options, /*use_provided=*/false, keypoints, nullptr);
}

void ComputeSurf(const cv::Mat& image, const SurfOptions& options,
                 std::vector<cv::KeyPoint>* keypoints, cv::Mat* descriptors) {
  PLACEDB_CHECK(descriptors != nullptr);
  Run(image, cv::Mat(), options, /*use_provided=*/true, keypoints, descriptors);
}

SurfFeature2D::SurfFeature2D(const SurfOptions& options) { setOptions(options); }

cv::Ptr<SurfFeature2D> SurfFeature2D::create(const SurfOptions& options) {
  return cv::makePtr<SurfFeature2D>(options);
}

void SurfFeature2D::detectAndCompute(cv::InputArray image, cv::InputArray mask,
                                     std::vector<cv::KeyPoint>& keypoints,
                                     cv::OutputArray descriptors, bool useProvidedKeypoints) {
  const cv::Mat img = image.getMat();
  const cv::Mat m = mask.getMat();
  if (!descriptors.needed()) {
    Run(img, m, options_, useProvidedKeypoints, &keypoints, nullptr);
    return;
  }
  cv::Mat desc;
  Run(img, m, options_, useProvidedKeypoints, &keypoints, &desc);
  descriptors.assign(desc);
}

int SurfFeature2D::descriptorSize() const { return DescriptorDim(options_); }

int SurfFeature2D::descriptorType() const { return CV_32F; }

int SurfFeature2D::defaultNorm() const { return cv::NORM_L2; }

cv::String SurfFeature2D::getDefaultName() const { return "placedb.SURF"; }

void SurfFeature2D::setOptions(const SurfOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  options_ = options;
}

}  // namespace placedb
