#include "placedb/eval/pictures.h"

#include <fmt/format.h>

#include <algorithm>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "placedb/dataset/frame.h"
#include "placedb/image/resize.h"
#include "placedb/util/check.h"

namespace placedb {
namespace {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kFontScale = 0.5;
constexpr int kBanner = 24;  // caption height, pixels

cv::Mat ToBgr(const cv::Mat& image) {
  cv::Mat bgr;
  if (image.channels() == 1) {
    cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, bgr, cv::COLOR_BGRA2BGR);
  } else {
    bgr = image.clone();
  }
  return bgr;
}

cv::Mat ScaledToHeight(const cv::Mat& bgr, int height, double* scale) {
  *scale = static_cast<double>(height) / bgr.rows;
  cv::Mat out;
  const int width = std::max(1, static_cast<int>(std::lround(bgr.cols * *scale)));
  cv::resize(bgr, out, cv::Size(width, height), 0, 0,
             *scale < 1.0 ? cv::INTER_AREA : cv::INTER_LINEAR);
  return out;
}

// `picture` with a dark banner of text lines above it.
cv::Mat WithCaption(const cv::Mat& picture, const std::vector<std::string>& lines) {
  if (lines.empty()) return picture;
  cv::Mat out(picture.rows + kBanner * static_cast<int>(lines.size()), picture.cols, CV_8UC3,
              cv::Scalar(40, 40, 40));
  picture.copyTo(out(cv::Rect(0, out.rows - picture.rows, picture.cols, picture.rows)));
  for (size_t i = 0; i < lines.size(); ++i) {
    cv::putText(out, lines[i], cv::Point(6, kBanner * static_cast<int>(i) + 17), kFont, kFontScale,
                cv::Scalar(240, 240, 240), 1, cv::LINE_AA);
  }
  return out;
}

void RequireImage(const cv::Mat& image, const char* what) {
  if (image.empty()) PLACEDB_THROW_INVALID("the ", what, " image is empty");
  if (image.depth() != CV_8U ||
      (image.channels() != 1 && image.channels() != 3 && image.channels() != 4)) {
    PLACEDB_THROW_INVALID("the ", what, " image must be 8-bit gray, BGR or BGRA");
  }
}

cv::Scalar ChannelColor(int channel) {
  switch (channel) {
    case 0: return cv::Scalar(40, 40, 230);   // r
    case 1: return cv::Scalar(40, 200, 40);   // g
    default: return cv::Scalar(230, 90, 30);  // b
  }
}

}  // namespace

cv::Mat DrawImageRow(const std::vector<cv::Mat>& images, const std::vector<std::string>& captions,
                     int height) {
  if (height < 32 || height > 4096) PLACEDB_THROW_INVALID("picture height must be in [32, 4096]");
  if (images.empty()) PLACEDB_THROW_INVALID("no images to draw");
  std::vector<cv::Mat> panels;
  for (size_t i = 0; i < images.size(); ++i) {
    cv::Mat panel;
    if (images[i].empty()) {
      panel = cv::Mat(height, height * 4 / 3, CV_8UC3, cv::Scalar(90, 90, 90));
      cv::putText(panel, "(no image)", cv::Point(10, height / 2), kFont, kFontScale,
                  cv::Scalar(240, 240, 240), 1, cv::LINE_AA);
    } else {
      RequireImage(images[i], "row");
      double scale = 1.0;
      panel = ScaledToHeight(ToBgr(images[i]), height, &scale);
    }
    const std::string caption = i < captions.size() ? captions[i] : "";
    panels.push_back(WithCaption(panel, {caption}));
    if (i + 1 < images.size()) panels.push_back(cv::Mat(panels.back().rows, 6, CV_8UC3,
                                                        cv::Scalar(255, 255, 255)));
  }
  cv::Mat row;
  cv::hconcat(panels, row);
  return row;
}

cv::Mat DrawMatchPicture(const MatchPicture& p) {
  RequireImage(p.query, "query");
  RequireImage(p.keyframe, "keyframe");
  if (p.height < 32 || p.height > 4096) {
    PLACEDB_THROW_INVALID("picture height must be in [32, 4096]");
  }
  const MatchDetail* d = p.detail;
  if (d != nullptr && !p.lost.empty() && p.lost.size() != d->matches.size()) {
    PLACEDB_THROW_INVALID("the lost list has ", p.lost.size(), " entries for ", d->matches.size(),
                          " matches");
  }
  double sq = 1.0, sk = 1.0;
  const cv::Mat q = ScaledToHeight(ToBgr(p.query), p.height, &sq);
  cv::Mat k = ScaledToHeight(ToBgr(p.keyframe), p.height, &sk);
  if (p.keyframe_is_original && p.region.area() > 0) {
    const cv::Rect r(cv::Point(static_cast<int>(p.region.x * sk), static_cast<int>(p.region.y * sk)),
                     cv::Size(static_cast<int>(p.region.width * sk),
                              static_cast<int>(p.region.height * sk)));
    cv::rectangle(k, r, kRegionColor, 2, cv::LINE_AA);
  }
  const int gap = 8;
  cv::Mat canvas(p.height, q.cols + gap + k.cols, CV_8UC3, cv::Scalar(255, 255, 255));
  q.copyTo(canvas(cv::Rect(0, 0, q.cols, q.rows)));
  k.copyTo(canvas(cv::Rect(q.cols + gap, 0, k.cols, k.rows)));
  int lost = 0;
  if (d != nullptr) {
    const std::vector<cv::Point2f>& kp =
        p.keyframe_is_original ? d->keyframe_points : d->keyframe_stored_points;
    // Draw order: plain matches, inliers, then the lost ones on top (lost
    // whether verified or not: cropping loses them either way).
    for (const int pass : {0, 2, 1}) {
      for (size_t i = 0; i < d->matches.size(); ++i) {
        const cv::DMatch& m = d->matches[i];
        if (m.queryIdx < 0 || static_cast<size_t>(m.queryIdx) >= d->query_keypoints.size() ||
            m.trainIdx < 0 || static_cast<size_t>(m.trainIdx) >= kp.size()) {
          PLACEDB_THROW_INVALID("match ", i, " refers to a keypoint that does not exist");
        }
        const bool is_lost = !p.lost.empty() && p.lost[i];
        const bool is_inlier = d->verified && i < d->inliers.size() && d->inliers[i];
        const int kind = is_lost ? 1 : is_inlier ? 2 : 0;
        if (kind != pass) continue;
        if (pass == 1) ++lost;
        const cv::Scalar color = kind == 2 ? kInlierColor : kind == 1 ? kLostColor : kMatchColor;
        const cv::Point2f a = d->query_keypoints[m.queryIdx].pt * sq;
        const cv::Point2f b = kp[m.trainIdx] * sk + cv::Point2f(static_cast<float>(q.cols + gap), 0);
        cv::circle(canvas, a, 3, color, 1, cv::LINE_AA);
        cv::circle(canvas, b, 3, color, 1, cv::LINE_AA);
        cv::line(canvas, a, b, color, 1, cv::LINE_AA);
      }
    }
  }
  std::vector<std::string> lines;
  if (!p.caption.empty()) lines.push_back(p.caption);
  if (d != nullptr) {
    std::string legend = fmt::format("{} matches", d->matches.size());
    if (d->verified) {
      legend += fmt::format(", {} verified; green: verified, amber: rejected", d->num_inliers);
    } else {
      legend += " (amber), not verified";
    }
    if (!p.lost.empty()) legend += fmt::format("; red: outside the crop, lost by cropping ({})", lost);
    lines.push_back(legend);
  }
  return WithCaption(canvas, lines);
}

cv::Mat LoadKeyframePicture(const PlaceDatabase& db, int32_t id, bool* keyframe_is_original) {
  const std::optional<Keyframe> k = db.FindKeyframe(id);
  if (!k) PLACEDB_THROW_INVALID("no keyframe ", id, " in the database ", db.directory());
  *keyframe_is_original = true;
  if (!k->source.empty()) {
    // The source path comes from the database file: read with the default
    // pixel bound, anything unreadable falls back to the stored image.
    cv::Mat original = TryReadImageFile(k->source, ImageReadOptions()).image;
    if (!original.empty() &&
        (k->original_size.area() == 0 || original.size() == k->original_size)) {
      return original;
    }
  }
  *keyframe_is_original = false;
  const std::string stored = db.StoredImagePath(*k);
  return stored.empty() ? cv::Mat() : TryReadImageFile(stored, ImageReadOptions()).image;
}

cv::Mat DrawQueryMatch(const PlaceDatabase& db, const cv::Mat& query_image,
                       const FeatureSet& query_features, int32_t id, const QueryOptions& options,
                       const std::string& caption, MatchDetail* detail) {
  MatchDetail d = db.Explain(query_features, id, options);
  MatchPicture p;
  p.query = query_image;
  p.keyframe = LoadKeyframePicture(db, id, &p.keyframe_is_original);
  if (p.keyframe.empty()) {
    PLACEDB_THROW_NOT_FOUND("cannot read keyframe ", id,
                            "'s image (neither its source nor a stored PNG)");
  }
  p.detail = &d;
  p.caption = caption;
  cv::Mat picture = DrawMatchPicture(p);
  if (detail != nullptr) *detail = std::move(d);
  return picture;
}

cv::Mat DrawCropIllustration(const cv::Mat& image, const CropResult& crop,
                             const CropOptions& options, const std::vector<int>& resizes) {
  RequireImage(image, "crop");
  const cv::Rect whole(0, 0, image.cols, image.rows);
  cv::Mat left = ToBgr(image);
  for (int c = 0; c < 3; ++c) {
    const CropCandidate& cand = crop.candidates[c];
    if (!cand.valid) continue;
    const bool winner = c == crop.channel;
    cv::rectangle(left, cand.roi & whole, ChannelColor(c), winner ? 4 : 2, cv::LINE_AA);
    const std::string label =
        fmt::format("{}: {} FAST{}", ChromaChannelName(static_cast<ChromaChannel>(c)),
                    cand.fast_keypoints, winner ? " (winner)" : "");
    int baseline = 0;
    const cv::Size text = cv::getTextSize(label, kFont, kFontScale, 3, &baseline);
    const cv::Point at(std::clamp(cand.roi.x + 4, 4, std::max(4, left.cols - text.width - 4)),
                       std::clamp(cand.roi.y + 18 + 18 * c, 16, std::max(16, left.rows - 6)));
    cv::putText(left, label, at, kFont, kFontScale, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
    cv::putText(left, label, at, kFont, kFontScale, ChannelColor(c), 1, cv::LINE_AA);
  }
  std::vector<cv::Mat> parts = {WithCaption(
      left, {crop.whole_image
                 ? fmt::format("no channel's crop reached {} FAST corners: the whole image is kept",
                               options.min_fast_keypoints)
                 : fmt::format("rg-chromaticity regions; the winner has the most FAST corners "
                               "(>= {})",
                               options.min_fast_keypoints)})};
  const cv::Mat kept = ToBgr(image)(crop.roi & whole);
  for (const int divisor : resizes) {
    if (!IsValidAreaDivisor(divisor)) PLACEDB_THROW_INVALID("bad area divisor ", divisor);
    const cv::Mat stored = ResizeByArea(kept, divisor);
    cv::Mat panel(left.rows, std::max(stored.cols, 150), CV_8UC3, cv::Scalar(255, 255, 255));
    // A crop of the image, downscaled: never taller than the image.
    stored.copyTo(panel(cv::Rect(0, 0, stored.cols, stored.rows)));
    parts.push_back(cv::Mat(parts.front().rows, 6, CV_8UC3, cv::Scalar(255, 255, 255)));
    parts.push_back(WithCaption(panel, {fmt::format("1/{}: {}x{}", divisor, stored.cols,
                                                    stored.rows)}));
  }
  cv::Mat out;
  cv::hconcat(parts, out);
  return out;
}

}  // namespace placedb
