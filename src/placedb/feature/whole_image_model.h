// The whole-image channel's HOG descriptor (WholeImageKind::kHog) and the
// model that makes it compact: HOG (OpenCV's HOGDescriptor, Dalal and
// Triggs) of a contrast-equalised thumbnail of the whole frame, projected on
// the map's principal components and whitened.
//
// Why these: on the dev set of summer and winter frames (Nordland, 1 576
// frames, not shipped; a slice is data/nordland64_slice), HOG of the
// CLAHE-equalised thumbnail with 4 x 4 cells ranked the right place first
// far more often than SeqSLAM's patch-normalised thumbnail, and a dense
// RootSIFT VLAD at that size ranked below both; projecting on the map's
// principal components with whitening (regularised: each component divided
// by sqrt(its variance + the mean variance), Jegou and Chum 2012) raised it
// further and makes the row small. The README's table of places that change
// shows HOG beside the thumbnail on the slice (make demo).
//
// The raw descriptor: the frame in grey, resized by area to width x height
// (multiples of 8), CLAHE (clip limit 2, 4 x 4 tiles), HOG with 16 x 16
// blocks, 8 px block stride, 4 x 4 cells, 9 unsigned orientation bins,
// L2-Hys; each value quantised to a byte: round(min(v, 0.5) x 510). Its
// length is HogRawDims(width, height).
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace placedb {

// Values of the raw HOG descriptor of a width x height thumbnail (both
// multiples of 8, at least 16): 5 040 for 64 x 48, 3 024 for 64 x 32.
int HogRawDims(int width, int height);

// The raw descriptor of an 8-bit grey, BGR or BGRA image: a 1 x
// HogRawDims(width, height) CV_8U row. Deterministic. InvalidArgument for
// an empty image, one that is not 8-bit, or sizes that are not multiples of
// 8 in [16, 128].
cv::Mat ComputeHogRaw(const cv::Mat& image, int width, int height);

// The thumbnail height that keeps a frame's aspect at `width`: width x
// rows / cols rounded to a multiple of 8, in [16, 128].
int HogHeightForFrame(int width, cv::Size frame);

// The projection: row = round(clamp(W (raw / 510 - mean) x 32, -127, 127)),
// W's rows the map's principal components divided by sqrt(variance + mean
// variance). A map of n keyframes has at most n - 1 components; the rows
// beyond them are 0 (and so are the values they give).
class WholeImageModel {
 public:
  // Fitted on `raw` (rows of HogRawDims(width, height) CV_8U values, one per
  // keyframe, at least 2) to `output_dims` values, deterministically (a
  // randomised SVD seeded by `seed`, Halko et al. 2011, on at most
  // kMaxFitRows rows spread evenly over the map). InvalidArgument for fewer
  // than 2 rows, rows of another length, output_dims outside [1, 4096].
  static WholeImageModel Fit(const std::vector<cv::Mat>& raw, int width, int height,
                             int output_dims, uint64_t seed = 1);
  static constexpr size_t kMaxFitRows = 8192;

  // A model from its parts (a file's). InvalidArgument when they do not
  // fit together or hold values that are not finite.
  WholeImageModel(int width, int height, int output_dims, std::vector<float> mean,
                  std::vector<float> projection);

  int width() const { return width_; }
  int height() const { return height_; }
  int input_dims() const { return static_cast<int>(mean_.size()); }
  int output_dims() const { return output_dims_; }
  // input_dims() values, and output_dims() x input_dims() row-major.
  const std::vector<float>& mean() const { return mean_; }
  const std::vector<float>& projection() const { return projection_; }

  // The 1 x output_dims() CV_8S row of a raw row (1 x input_dims() CV_8U).
  cv::Mat Project(const cv::Mat& raw) const;
  // ComputeHogRaw then Project.
  cv::Mat Describe(const cv::Mat& image) const;

 private:
  int width_ = 0, height_ = 0, output_dims_ = 0;
  std::vector<float> mean_;
  std::vector<float> projection_;
};

}  // namespace placedb
