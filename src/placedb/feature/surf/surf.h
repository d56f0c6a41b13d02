// SURF: Speeded-Up Robust Features (Bay, Ess, Tuytelaars, Van Gool, CVIU 2008),
// implemented from the paper because Debian's OpenCV has no xfeatures2d.
//
// Conventions (the same as OpenCV's SURF wherever the paper leaves a choice):
//  - Filter sizes: octave o, layer l in [0, num_octave_layers + 2) uses a box
//    filter of side (9 + 6 l) * 2^o pixels, sampled every 2^o pixels. Extrema
//    are searched in the num_octave_layers inner layers of each octave (so 3
//    layers -> 5 filter sizes per octave: 9 15 21 27 33, 18 30 ... ; 2 layers
//    is the paper's 4 filter sizes per octave).
//  - Responses: each box of Dxx, Dyy, Dxy is divided by its own area (box means
//    in 0..255 grey levels), det = Dxx Dyy - (0.9 Dxy)^2. This is OpenCV's
//    normalisation, so hessian_threshold means the same as OpenCV's
//    hessianThreshold (typical values 100..1000).
//  - cv::KeyPoint fields: pt = sub-pixel position (pixel centres at integer
//    coordinates); size = interpolated filter side in pixels (9 at the finest
//    scale), the feature's scale is s = 1.2 * size / 9 and its descriptor
//    window is 20 s wide; angle = orientation in degrees in [0, 360), measured
//    in image coordinates (x right, y down, so clockwise on screen), and 0 in
//    upright mode; response = Hessian determinant; octave = octave index;
//    class_id = sign of the Laplacian Dxx + Dyy (+1 or -1; -1 = bright blob on
//    dark background), usable to reject matches cheaply.
//  - Descriptors: CV_32F, one row per keypoint, 64 or 128 columns, each row of
//    unit L2 norm (a row is all zeros only for a perfectly flat patch, which
//    the detector never returns but a provided keypoint can lie on).
#pragma once

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <string>
#include <vector>

#include "placedb/feature/surf/surf_options.h"

namespace placedb {

// Detects SURF keypoints and computes their descriptors.
// image: CV_8UC1, or CV_8UC3 / CV_8UC4 (BGR / BGRA, converted to grey). An
// empty image, or one too small or too flat to hold a feature, gives zero
// keypoints and a 0 x 64 (or 0 x 128) descriptor matrix; other types throw
// InvalidArgument. descriptors may be null (detection only).
void DetectAndComputeSurf(const cv::Mat& image, const SurfOptions& options,
                          std::vector<cv::KeyPoint>* keypoints, cv::Mat* descriptors);

// Detection only: the same keypoints (with orientation unless upright) as
// DetectAndComputeSurf.
void DetectSurf(const cv::Mat& image, const SurfOptions& options,
                std::vector<cv::KeyPoint>* keypoints);

// Computes orientation (unless options.upright) and descriptors for the given
// keypoints, whose pt and size are used as they are (angle, response, octave
// and class_id are rewritten). Keypoints are never removed; rows of
// *descriptors follow *keypoints.
void ComputeSurf(const cv::Mat& image, const SurfOptions& options,
                 std::vector<cv::KeyPoint>* keypoints, cv::Mat* descriptors);

// cv::Feature2D wrapper: usable wherever an OpenCV detector/extractor is.
// detect() honours a CV_8UC1 mask; compute() / detectAndCompute(...,
// useProvidedKeypoints = true) describe the given keypoints (see ComputeSurf).
class SurfFeature2D : public cv::Feature2D {
 public:
  explicit SurfFeature2D(const SurfOptions& options = SurfOptions());

  static cv::Ptr<SurfFeature2D> create(const SurfOptions& options = SurfOptions());

  void detectAndCompute(cv::InputArray image, cv::InputArray mask,
                        std::vector<cv::KeyPoint>& keypoints, cv::OutputArray descriptors,
                        bool useProvidedKeypoints = false) override;

  int descriptorSize() const override;         // 64 or 128.
  int descriptorType() const override;         // CV_32F.
  int defaultNorm() const override;            // cv::NORM_L2.
  cv::String getDefaultName() const override;  // "placedb.SURF".
  bool empty() const override { return false; }

  const SurfOptions& options() const { return options_; }
  // Throws InvalidArgument when options.Check() fails.
  void setOptions(const SurfOptions& options);

 private:
  SurfOptions options_;
};

}  // namespace placedb
