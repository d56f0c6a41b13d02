// Pictures of what placedb did, for reports and `placedb query --draw`: a
// query beside a keyframe with the matches joined by lines (the paper's
// Figs. 4-7), the feature-rich crop's candidate regions with their FAST
// counts and the stored sizes (Fig. 14), and rows of captioned images (the
// report's grid of failed queries). Pure drawing on OpenCV images: no I/O
// except LoadKeyframePicture, which reads the image a keyframe came from.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "placedb/image/feature_rich_crop.h"
#include "placedb/session/place_database.h"
#include "placedb/query/result.h"

namespace placedb {

// Colours of the lines (BGR).
inline const cv::Scalar kInlierColor(80, 200, 60);     // verified matches: green
inline const cv::Scalar kMatchColor(0, 200, 255);      // matches not verified: amber
inline const cv::Scalar kLostColor(60, 60, 230);       // matches cropping lost: red
inline const cv::Scalar kRegionColor(255, 160, 40);    // a keyframe's crop: blue

struct MatchPicture {
  cv::Mat query;     // the query image (8-bit gray or BGR)
  cv::Mat keyframe;  // the keyframe's image: its original, or its stored PNG
  // Whether `keyframe` is the original image (points: keyframe_points) or
  // the stored one (keyframe_stored_points).
  bool keyframe_is_original = true;
  const MatchDetail* detail = nullptr;  // the matches (nullptr: none drawn)
  // Per match, 1: drawn in kLostColor (e.g. the matches cropping lost);
  // empty: none.
  std::vector<uint8_t> lost;
  // A region of the keyframe's original image outlined (e.g. its crop);
  // empty: none. Drawn only on an original image.
  cv::Rect region;
  std::string caption;  // a line above the picture
  // Each image is scaled so that its height is this many pixels. Range
  // [32, 4096]. Default 360.
  int height = 360;
};

// The query (left) beside the keyframe (right), matches joined by lines:
// inliers green, other matches amber, lost ones red; a legend with counts.
// Throws InvalidArgument for empty images, a bad height or a `lost`
// list of the wrong length.
cv::Mat DrawMatchPicture(const MatchPicture& picture);

// The image keyframe `id` of `db` is best drawn on: its source image when
// readable at the recorded original size (keyframe_is_original), else its
// stored PNG; empty when neither can be read.
cv::Mat LoadKeyframePicture(const PlaceDatabase& db, int32_t id, bool* keyframe_is_original);

// The query against keyframe `id` of `db` as a picture: Explain + the
// keyframe's image + DrawMatchPicture. Throws InvalidArgument for an unknown
// id, NotFound when the keyframe's image cannot be read (neither its source
// nor a stored PNG).
cv::Mat DrawQueryMatch(const PlaceDatabase& db, const cv::Mat& query_image,
                       const FeatureSet& query_features, int32_t id, const QueryOptions& options,
                       const std::string& caption, MatchDetail* detail = nullptr);

// The feature-rich crop of `image` as the builder chose it: each
// rg-chromaticity channel's region in its colour with its FAST count, the
// winner thick, the threshold; then the kept region stored at each area
// divisor in `resizes` (1, 4, 16), drawn at its true pixel size.
cv::Mat DrawCropIllustration(const cv::Mat& image, const CropResult& crop,
                             const CropOptions& options, const std::vector<int>& resizes);

// Images side by side, each scaled to `height` pixels, each with a caption
// above it. Empty images are drawn as grey panels saying "(no image)".
cv::Mat DrawImageRow(const std::vector<cv::Mat>& images, const std::vector<std::string>& captions,
                     int height);

}  // namespace placedb
