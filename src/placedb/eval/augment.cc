#include "placedb/eval/augment.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "placedb/util/check.h"
#include "placedb/util/options.h"

namespace placedb {

namespace {

// SplitMix64's finaliser: a well-mixed 64-bit value from any input.
uint64_t Mix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// "" when lo <= hi, else why not (the bounds of one drawn range).
std::string CheckOrder(const std::string& lo_name, double lo, const std::string& hi_name,
                       double hi) {
  if (lo <= hi) return "";
  return lo_name + " must not exceed " + hi_name + " (got " + std::to_string(lo) + " > " +
         std::to_string(hi) + ")";
}

// An 8-bit BGR view of `source` (gray and BGRA converted).
cv::Mat ToBgr(const cv::Mat& source) {
  if (source.empty()) PLACEDB_THROW_INVALID("cannot augment an empty image");
  if (source.depth() != CV_8U) {
    PLACEDB_THROW_INVALID("augmentation needs an 8-bit image (got ",
                          cv::typeToString(source.type()), ")");
  }
  if (source.channels() == 3) return source;
  cv::Mat bgr;
  if (source.channels() == 1) {
    cv::cvtColor(source, bgr, cv::COLOR_GRAY2BGR);
  } else if (source.channels() == 4) {
    cv::cvtColor(source, bgr, cv::COLOR_BGRA2BGR);
  } else {
    PLACEDB_THROW_INVALID("augmentation needs 1, 3 or 4 channels (got ", source.channels(), ")");
  }
  return bgr;
}

}  // namespace

std::string AugmentOptions::Check() const {
  return FirstReason(
      {CheckRange("width", width, 16, 8192), CheckRange("height", height, 16, 8192),
       CheckRange("min_crop", min_crop, 0.0, 1.0, true),
       CheckRange("max_crop", max_crop, 0.0, 1.0, true),
       CheckOrder("min_crop", min_crop, "max_crop", max_crop),
       CheckRange("max_rotation_deg", max_rotation_deg, 0.0, 45.0),
       CheckRange("max_perspective", max_perspective, 0.0, 0.25),
       CheckRange("min_blur_sigma", min_blur_sigma, 0.0, 10.0),
       CheckRange("max_blur_sigma", max_blur_sigma, 0.0, 10.0),
       CheckOrder("min_blur_sigma", min_blur_sigma, "max_blur_sigma", max_blur_sigma),
       CheckRange("max_brightness", max_brightness, 0.0, 128.0),
       CheckRange("max_contrast", max_contrast, 0.0, 0.9),
       CheckRange("max_gamma", max_gamma, 0.0, 0.9),
       CheckRange("min_noise_sigma", min_noise_sigma, 0.0, 64.0),
       CheckRange("max_noise_sigma", max_noise_sigma, 0.0, 64.0),
       CheckOrder("min_noise_sigma", min_noise_sigma, "max_noise_sigma", max_noise_sigma)});
}

nlohmann::json AugmentOptionsToJson(const AugmentOptions& o) {
  return {{"width", o.width},
          {"height", o.height},
          {"min_crop", o.min_crop},
          {"max_crop", o.max_crop},
          {"max_rotation_deg", o.max_rotation_deg},
          {"max_perspective", o.max_perspective},
          {"min_blur_sigma", o.min_blur_sigma},
          {"max_blur_sigma", o.max_blur_sigma},
          {"max_brightness", o.max_brightness},
          {"max_contrast", o.max_contrast},
          {"max_gamma", o.max_gamma},
          {"min_noise_sigma", o.min_noise_sigma},
          {"max_noise_sigma", o.max_noise_sigma},
          {"seed", o.seed}};
}

AugmentParams DrawAugmentParams(cv::Size source_size, uint64_t seed,
                                const AugmentOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  if (source_size.width < 2 || source_size.height < 2) {
    PLACEDB_THROW_INVALID("an augmentation source needs at least 2 x 2 pixels (got ",
                          source_size.width, " x ", source_size.height, ")");
  }
  cv::RNG rng(Mix(Mix(options.seed) ^ seed));
  AugmentParams p;
  // The largest rectangle of the output's aspect ratio inside the source,
  // then the crop's share of it.
  const double max_x = source_size.width - 1.0, max_y = source_size.height - 1.0;
  const double aspect = static_cast<double>(options.width) / options.height;
  const double base_w = std::min(max_x, max_y * aspect);
  const double base_h = base_w / aspect;
  p.crop = rng.uniform(options.min_crop, options.max_crop);
  p.rotation_deg = rng.uniform(-options.max_rotation_deg, options.max_rotation_deg);
  const double w = p.crop * base_w, h = p.crop * base_h;
  const double theta = p.rotation_deg * CV_PI / 180.0;
  const double c = std::cos(theta), s = std::sin(theta);
  const double unit[4][2] = {{-0.5, -0.5}, {0.5, -0.5}, {0.5, 0.5}, {-0.5, 0.5}};
  double rel[4][2];
  double min_x = std::numeric_limits<double>::max(), max_rx = -min_x;
  double min_y = min_x, max_ry = -min_x;
  for (int i = 0; i < 4; ++i) {
    const double jx = rng.uniform(-options.max_perspective, options.max_perspective);
    const double jy = rng.uniform(-options.max_perspective, options.max_perspective);
    const double x = (unit[i][0] + jx) * w, y = (unit[i][1] + jy) * h;
    rel[i][0] = c * x - s * y;
    rel[i][1] = s * x + c * y;
    min_x = std::min(min_x, rel[i][0]);
    max_rx = std::max(max_rx, rel[i][0]);
    min_y = std::min(min_y, rel[i][1]);
    max_ry = std::max(max_ry, rel[i][1]);
  }
  // Shrink a quadrilateral that does not fit (a large crop turned), then
  // place it uniformly where it fits.
  const double fit = std::min({1.0, max_x / (max_rx - min_x), max_y / (max_ry - min_y)});
  p.crop *= fit;
  const double cx = rng.uniform(-min_x * fit, max_x - max_rx * fit);
  const double cy = rng.uniform(-min_y * fit, max_y - max_ry * fit);
  p.center = cv::Point2f(static_cast<float>(cx), static_cast<float>(cy));
  for (int i = 0; i < 4; ++i) {
    const double x = std::clamp(cx + rel[i][0] * fit, 0.0, max_x);
    const double y = std::clamp(cy + rel[i][1] * fit, 0.0, max_y);
    p.corners[i] = cv::Point2f(static_cast<float>(x), static_cast<float>(y));
  }
  p.blur_sigma = rng.uniform(options.min_blur_sigma, options.max_blur_sigma);
  p.brightness = rng.uniform(-options.max_brightness, options.max_brightness);
  p.contrast = 1.0 + rng.uniform(-options.max_contrast, options.max_contrast);
  p.gamma = 1.0 + rng.uniform(-options.max_gamma, options.max_gamma);
  p.noise_sigma = rng.uniform(options.min_noise_sigma, options.max_noise_sigma);
  const uint64_t high = rng.next();
  p.noise_seed = Mix(high << 32 | rng.next());
  return p;
}

cv::Mat Augment(const cv::Mat& source, uint64_t seed, const AugmentOptions& options) {
  const cv::Mat bgr = ToBgr(source);
  const AugmentParams p = DrawAugmentParams(bgr.size(), seed, options);
  const float w = options.width - 1.0f, h = options.height - 1.0f;
  const cv::Point2f target[4] = {{0, 0}, {w, 0}, {w, h}, {0, h}};
  cv::Mat warped;
  cv::warpPerspective(bgr, warped, cv::getPerspectiveTransform(p.corners, target),
                      cv::Size(options.width, options.height), cv::INTER_LINEAR,
                      cv::BORDER_REPLICATE);
  if (p.blur_sigma >= 0.1) cv::GaussianBlur(warped, warped, cv::Size(0, 0), p.blur_sigma);
  cv::Mat lut(1, 256, CV_8U);
  for (int i = 0; i < 256; ++i) {
    lut.at<uint8_t>(i) = cv::saturate_cast<uint8_t>(255.0 * std::pow(i / 255.0, p.gamma));
  }
  cv::LUT(warped, lut, warped);
  cv::Mat values;
  warped.convertTo(values, CV_32FC3, p.contrast, 128.0 * (1.0 - p.contrast) + p.brightness);
  if (p.noise_sigma > 0.0) {
    cv::Mat noise(values.size(), CV_32FC3);
    cv::RNG rng(p.noise_seed);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, p.noise_sigma);
    values += noise;
  }
  cv::Mat out;
  values.convertTo(out, CV_8UC3);
  return out;
}

uint64_t AugmentedFrameSeed(uint64_t seed, int id) {
  return Mix(Mix(seed) ^ static_cast<uint64_t>(id));
}

Pose AugmentedPose(int source_index, cv::Size source_size, const AugmentParams& params) {
  Pose pose;
  pose.translation = Eigen::Vector3d(
      source_index + 0.1 * (params.center.x / (source_size.width - 1.0) - 0.5),
      0.1 * (params.center.y / (source_size.height - 1.0) - 0.5), 0.05 * (1.0 - params.crop));
  pose.rotation = Eigen::Quaterniond(
      Eigen::AngleAxisd(params.rotation_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ()));
  return pose;
}

std::vector<Frame> AugmentedFrames(const std::vector<std::string>& sources, size_t count,
                                   uint64_t seed, const AugmentOptions& options) {
  PLACEDB_CHECK_OPTIONS(options);
  if (sources.empty()) PLACEDB_THROW_INVALID("no source images to augment");
  if (count < 1 || count > static_cast<size_t>(std::numeric_limits<int32_t>::max())) {
    PLACEDB_THROW_INVALID("the number of augmented frames must be in [1, 2^31) (got ", count, ")");
  }
  std::vector<std::shared_ptr<const cv::Mat>> images;
  images.reserve(sources.size());
  for (const std::string& path : sources) {
    const DecodedImage decoded = TryReadImageFile(path, ImageReadOptions());
    if (decoded.image.empty()) {
      ThrowImageError(decoded, "cannot read augmentation source " + path + ": " + decoded.error);
    }
    cv::Mat image = decoded.image;
    if (image.cols < 2 || image.rows < 2) {
      PLACEDB_THROW_INVALID("augmentation source ", path, " is smaller than 2 x 2 pixels");
    }
    images.push_back(std::make_shared<const cv::Mat>(std::move(image)));
  }
  std::vector<Frame> frames(count);
  for (size_t i = 0; i < count; ++i) {
    const int id = static_cast<int>(i) + 1;
    const size_t s = i % sources.size();
    const uint64_t frame_seed = AugmentedFrameSeed(seed, id);
    std::shared_ptr<const cv::Mat> image = images[s];
    Frame& f = frames[i];
    f.id = id;
    f.timestamp = id;
    f.image_path = sources[s] + "#aug" + std::to_string(id);
    f.pose = AugmentedPose(static_cast<int>(s), image->size(),
                           DrawAugmentParams(image->size(), frame_seed, options));
    f.load = [image, frame_seed, options] { return Augment(*image, frame_seed, options); };
  }
  return frames;
}

}  // namespace placedb
