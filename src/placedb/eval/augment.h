// Synthetic keyframe sets for the scale benchmark: many distinct views made
// from a few sample images by a random crop, rotation and perspective warp,
// blur, and photometric changes (brightness, contrast, gamma, noise).
//
// One augmentation, drawn from (options.seed, seed) alone:
//  1. geometry: a rectangle of the output's aspect ratio, `crop` times the
//     largest one the source holds (per side), rotated by up to
//     max_rotation_deg, each corner moved by up to max_perspective of the
//     side, shrunk if needed so that the quadrilateral lies inside the
//     source, and placed uniformly where it fits; warpPerspective maps it
//     onto the output (bilinear), so every output pixel comes from the
//     source (no invented border);
//  2. Gaussian blur with a sigma in [min_blur_sigma, max_blur_sigma];
//  3. gamma (a lookup table), then contrast about mid-grey and brightness;
//  4. Gaussian noise (per pixel and channel) with a sigma in
//     [min_noise_sigma, max_noise_sigma] grey levels; saturated to 8 bits.
//
// AugmentedFrames makes a keyframe set whose images are generated on demand
// (Frame::load) from sources decoded once, with a timestamp and a synthetic
// pose per keyframe so that time- and pose-based clusters exist.
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "placedb/dataset/frame.h"
#include "placedb/util/pose.h"

namespace placedb {

struct AugmentOptions {
  // Output size in pixels. Range [16, 8192] each. Default 320 x 240.
  int width = 320;
  int height = 240;
  // Fraction of the source's side kept by the crop (of the largest rectangle
  // of the output's aspect ratio that fits the source), drawn uniformly in
  // [min_crop, max_crop]. Range (0, 1], min_crop <= max_crop. Default
  // [0.5, 0.9].
  double min_crop = 0.5;
  double max_crop = 0.9;
  // Rotation of the crop, uniform in +-max_rotation_deg degrees. Range
  // [0, 45]. Default 10.
  double max_rotation_deg = 10.0;
  // Perspective jitter: each crop corner moves by up to this fraction of the
  // crop's side, in x and y independently. Range [0, 0.25]. Default 0.05.
  double max_perspective = 0.05;
  // Gaussian blur sigma in pixels (of the output), uniform in [min, max];
  // below 0.1 no blur. Range [0, 10], min <= max. Default [0, 1.5].
  double min_blur_sigma = 0.0;
  double max_blur_sigma = 1.5;
  // Brightness offset, uniform in +-max_brightness grey levels. Range
  // [0, 128]. Default 20.
  double max_brightness = 20.0;
  // Contrast gain about mid-grey (128), uniform in [1 - c, 1 + c]. Range
  // [0, 0.9]. Default 0.2.
  double max_contrast = 0.2;
  // Gamma, uniform in [1 - g, 1 + g] (out = 255 (in / 255)^gamma). Range
  // [0, 0.9]. Default 0.2.
  double max_gamma = 0.2;
  // Gaussian noise sigma in grey levels, uniform in [min, max]. Range
  // [0, 64], min <= max. Default [0, 4].
  double min_noise_sigma = 0.0;
  double max_noise_sigma = 4.0;
  // Mixed into every augmentation's seed, so that one option set gives a
  // family of views distinct from another's. Any value. Default 0.
  uint64_t seed = 0;

  std::string Check() const;
};

// Every field, for reports and for recognising a benchmark database built
// with the same settings.
nlohmann::json AugmentOptionsToJson(const AugmentOptions& options);

// The random draws of one augmentation of a `source`-sized image.
struct AugmentParams {
  // The source quadrilateral mapped onto the output's corners (top-left,
  // top-right, bottom-right, bottom-left), inside [0, w-1] x [0, h-1].
  cv::Point2f corners[4];
  cv::Point2f center;  // of the quadrilateral, source pixels
  double crop = 1.0;   // fraction of the side kept (after any shrinking)
  double rotation_deg = 0.0;
  double blur_sigma = 0.0;
  double brightness = 0.0;
  double contrast = 1.0;
  double gamma = 1.0;
  double noise_sigma = 0.0;
  uint64_t noise_seed = 0;
};

// The draws for (options.seed, seed) on a source of `source_size` (each side
// at least 2 pixels; InvalidArgument otherwise or for bad options).
AugmentParams DrawAugmentParams(cv::Size source_size, uint64_t seed, const AugmentOptions& options);

// One augmentation of `source` (8-bit gray, BGR or BGRA): an 8-bit BGR image
// of options.width x options.height, the same for the same (source, seed,
// options) on any thread. An empty source, another depth or bad options are
// InvalidArgument.
cv::Mat Augment(const cv::Mat& source, uint64_t seed, const AugmentOptions& options);

// The seed of keyframe `id` (1-based) of a set made with `seed`.
uint64_t AugmentedFrameSeed(uint64_t seed, int id);

// A synthetic keyframe set of `count` frames, ids 1..count. Frame k is an
// augmentation of source (k - 1) % sources.size() with AugmentedFrameSeed(
// seed, k); its `load` generates the image on each call (thread-safe: the
// sources are decoded once, here, and shared read-only). Timestamp k
// seconds. Pose: the sources stand on a line, source s at x = s metres
// (y = z = 0); each view is offset by its crop centre (x, y: up to +-5 cm
// over the source's width and height) and crop size (z: up to 5 cm), and
// turned about the optical axis by its rotation. image_path describes the
// frame ("<source>#aug<k>"). A missing source is NotFound, one that is not
// an image InvalidArgument; no sources, or a count outside [1, 2^31),
// InvalidArgument.
std::vector<Frame> AugmentedFrames(const std::vector<std::string>& sources, size_t count,
                                   uint64_t seed, const AugmentOptions& options);

// The pose AugmentedFrames gives a view of source `source_index` drawn with
// `params` on a source of `source_size`.
Pose AugmentedPose(int source_index, cv::Size source_size, const AugmentParams& params);

}  // namespace placedb
