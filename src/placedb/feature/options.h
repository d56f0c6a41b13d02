// The options of feature extraction: ORB's, our SURF's, and what every
// extractor shares (part of the public face, placedb/placedb.h).
#pragma once

#include <string>

#include "placedb/feature/surf/surf_options.h"
#include "placedb/feature/types.h"
#include "placedb/util/option_table.h"

namespace placedb {

// OpenCV ORB's settings (defaults equal to cv::ORB::create()'s).
struct OrbOptions {
  // Most keypoints kept per image (strongest by Harris score). Range
  // [1, 100000]. Default 500.
  int max_features = 500;
  // Pyramid decimation ratio between levels. Range (1, 4]. Default 1.2.
  double scale_factor = 1.2;
  // Number of pyramid levels. Range [1, 32]. Default 8.
  int num_levels = 8;
  // Border without features, pixels (should match patch_size). Range
  // [0, 512]. Default 31.
  int edge_threshold = 31;
  // FAST threshold used by ORB's detector. Range [1, 255]. Default 20.
  int fast_threshold = 20;
  // Size of the BRIEF patch, pixels. Range [2, 512]. Default 31.
  int patch_size = 31;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<OrbOptions>& Table();
  std::string Check() const;
};

// The descriptor of the whole-image channel.
enum class WholeImageKind {
  kThumbnail = 0,  // SeqSLAM's patch-normalised thumbnail (width x height values)
  kHog = 1,        // HOG of a contrast-equalised thumbnail, PCA-whitened by a model of the map
};
const char* WholeImageKindName(WholeImageKind kind);
// "thumbnail" or "hog"; InvalidArgument otherwise.
WholeImageKind ParseWholeImageKind(const std::string& name);

// The whole-image channel (feature/whole_image.h): one row of int8 values
// per keyframe and query, SeqSLAM's patch-normalised thumbnail or a
// PCA-whitened HOG of the whole frame.
struct WholeImageOptions {
  // Which descriptor. Default kHog (docs' "places that change" table: it
  // survives light and season where the thumbnail does not); a manifest
  // without the key reads kThumbnail (databases of earlier versions).
  WholeImageKind kind = WholeImageKind::kHog;
  // Thumbnail width and height, pixels. Range [4, 64]. Default 32 x 24.
  int width = 32;
  int height = 24;
  // Side of the normalised tiles, pixels. Range [2, 64], at most
  // min(width, height). Default 8.
  int patch = 8;
  // Whether extraction computes it (and a database keeps it). Default true;
  // a manifest written before the channel existed reads as false.
  bool enabled = true;
  // kHog: the thumbnail's width, pixels (a multiple of 8). Range [16, 128].
  // Default 64.
  int hog_width = 64;
  // kHog: its height (a multiple of 8); 0: from the map's first frame, its
  // aspect kept (64 x 48 for 4:3 frames, 64 x 32 for 2:1), which the build
  // records. Range 0 or [16, 128]. Default 0.
  int hog_height = 0;
  // kHog: values per row after the model's projection (the map's principal
  // components, whitened; a map of fewer keyframes has fewer components and
  // the rest of the row is 0). Range [16, 1024]. Default 512 (512 bytes per
  // keyframe).
  int hog_dims = 512;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<WholeImageOptions>& Table();
  std::string Check() const;
};

struct ExtractorOptions {
  // Which descriptor to compute. Default ORB.
  FeatureType type = FeatureType::kOrb;
  OrbOptions orb;
  SurfOptions surf;
  // Small frames: an image whose shorter side is below this many pixels is
  // upscaled (bilinear) until it is this long (at most 4x) for extraction,
  // and the keypoints are mapped back to the image (position, size). ORB's 31-px
  // patch and border leave little of a 160x120 frame. 0 disables. Range
  // [0, 4096]. Default 240 (measured on data/rtabmap_loop shrunk to 160x120:
  // recall@1 0.909 without, 0.977 with; 320x240 frames are not upscaled).
  int upscale_below = 240;
  // ORB's FAST threshold for the frames upscaled above by 2x or more (a
  // shorter side at most upscale_below / 2): an upscaled tiny frame is
  // blurred, and the library's 20 finds few corners in it. (Frames upscaled
  // less keep orb.fast_threshold: stored images of 1/4 the area did worse
  // with it.) 0: the same as orb.fast_threshold. Range [0, 255]. Default 5 (measured on
  // data/rtabmap_loop read at 40x30: recall@1 0.841 with 20, 0.909 with 5;
  // at 64x48 0.932 -> 0.955, at 80x60 0.932 -> 0.977, 160x120 unchanged;
  // frames of 240 px and more are not upscaled). Manifests without the key
  // read as 0: databases of earlier versions keep their extraction.
  int upscaled_fast_threshold = 5;
  // Local features under changed light: the grey frame is contrast-equalised
  // (CLAHE: clip limit 2, 8 x 8 tiles, before any upscaling) before
  // detection and description, for the map's frames and the queries alike
  // (the database records it). The whole-image channel equalises its own
  // thumbnail either way. Default false (docs' "places that change" table
  // has what it gives); manifests without the key read false.
  bool clahe = false;
  // The whole-image descriptor (FeatureSet::whole_image), computed on the
  // image as given, before any upscaling.
  WholeImageOptions whole_image;

  // The options' names, defaults, ranges and help (util/option_table.h).
  static const OptionTable<ExtractorOptions>& Table();
  std::string Check() const;
};

}  // namespace placedb
