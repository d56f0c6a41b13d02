// The option tables of the feature stage: ORB and what every extractor
// shares (util/option_table.h; SURF's is in surf/surf_options.cc).
#include "placedb/feature/options.h"
#include "placedb/util/option_table.h"
#include "placedb/util/check.h"

#include <algorithm>
#include <string>

namespace placedb {

const OptionTable<OrbOptions>& OrbOptions::Table() {
  static const OptionTable<OrbOptions> table = [] {
    using O = OrbOptions;
    OptionTable<O> t("ORB options");
    t.Number("orb_max_features", PLACEDB_MEMBER(O, max_features), OptionRange::Closed(1, 100000),
             "ORB: most keypoints per image");
    t.Number("orb_scale_factor", PLACEDB_MEMBER(O, scale_factor), OptionRange::LeftOpen(1, 4),
             "ORB: pyramid scale factor");
    t.Number("orb_levels", PLACEDB_MEMBER(O, num_levels), OptionRange::Closed(1, 32),
             "ORB: pyramid levels");
    t.Number("orb_edge_threshold", PLACEDB_MEMBER(O, edge_threshold), OptionRange::Closed(0, 512),
             "ORB: border without features, px");
    t.Number("orb_fast_threshold", PLACEDB_MEMBER(O, fast_threshold), OptionRange::Closed(1, 255),
             "ORB: FAST threshold");
    t.Number("orb_patch_size", PLACEDB_MEMBER(O, patch_size), OptionRange::Closed(2, 512),
             "ORB: BRIEF patch size, px");
    return t;
  }();
  return table;
}

std::string OrbOptions::Check() const { return Table().Check(*this); }

const OptionTable<WholeImageOptions>& WholeImageOptions::Table() {
  static const OptionTable<WholeImageOptions> table = [] {
    using O = WholeImageOptions;
    const O defaults;
    OptionTable<O> t("whole-image options");
    // Manifests written before the whole-image channel lack these keys:
    // their databases have no channel, and the sizes mean nothing there.
    t.Number("whole_image_width", PLACEDB_MEMBER(O, width), OptionRange::Closed(4, 64),
             "whole image: thumbnail width, px")
        .absent = int64_t{defaults.width};
    t.Number("whole_image_height", PLACEDB_MEMBER(O, height), OptionRange::Closed(4, 64),
             "whole image: thumbnail height, px")
        .absent = int64_t{defaults.height};
    t.Number("whole_image_patch", PLACEDB_MEMBER(O, patch), OptionRange::Closed(2, 64),
             "whole image: side of the normalised tiles, px")
        .absent = int64_t{defaults.patch};
    t.Bool("whole_image", PLACEDB_MEMBER(O, enabled),
           "whole-image channel: a descriptor of the whole image per keyframe and query",
           BoolFlag::kNegatable)
        .absent = false;
    t.Choice("whole_image_kind", PLACEDB_MEMBER(O, kind),
             {WholeImageKind::kThumbnail, WholeImageKind::kHog}, ParseWholeImageKind,
             WholeImageKindName,
             "whole image: thumbnail (SeqSLAM's patch-normalised thumbnail) or hog (HOG of a "
             "contrast-equalised thumbnail, PCA-whitened by a model of the map)")
        .absent = std::string("thumbnail");
    t.Number("whole_image_hog_width", PLACEDB_MEMBER(O, hog_width), OptionRange::Closed(16, 128),
             "whole image, hog: thumbnail width, px (a multiple of 8)")
        .absent = int64_t{defaults.hog_width};
    t.Number("whole_image_hog_height", PLACEDB_MEMBER(O, hog_height), OptionRange::Closed(0, 128),
             "whole image, hog: thumbnail height, px (a multiple of 8; 0: the map's aspect)")
        .absent = int64_t{defaults.hog_height};
    t.Number("whole_image_hog_dims", PLACEDB_MEMBER(O, hog_dims), OptionRange::Closed(16, 1024),
             "whole image, hog: values per row after the map's PCA")
        .absent = int64_t{defaults.hog_dims};
    t.Rule([](const O& o) -> std::string {
      if (o.hog_width % 8 != 0) return "`whole_image_hog_width` must be a multiple of 8";
      if (o.hog_height != 0 && (o.hog_height < 16 || o.hog_height % 8 != 0))
        return "`whole_image_hog_height` must be 0 or a multiple of 8 in [16, 128]";
      if (o.patch > std::min(o.width, o.height)) {
        return "`whole_image_patch` must be at most the smaller of `whole_image_width` and "
               "`whole_image_height` (" +
               std::to_string(std::min(o.width, o.height)) + ")";
      }
      return "";
    });
    return t;
  }();
  return table;
}

std::string WholeImageOptions::Check() const { return Table().Check(*this); }

const char* WholeImageKindName(WholeImageKind kind) {
  return kind == WholeImageKind::kHog ? "hog" : "thumbnail";
}

WholeImageKind ParseWholeImageKind(const std::string& name) {
  if (name == "thumbnail") return WholeImageKind::kThumbnail;
  if (name == "hog") return WholeImageKind::kHog;
  PLACEDB_THROW_INVALID("unknown whole-image kind '", name, "' (thumbnail or hog)");
}

const OptionTable<ExtractorOptions>& ExtractorOptions::Table() {
  static const OptionTable<ExtractorOptions> table = [] {
    using O = ExtractorOptions;
    OptionTable<O> t("feature options");
    t.Choice("features", PLACEDB_MEMBER(O, type), {FeatureType::kOrb, FeatureType::kSurf},
             ParseFeatureType, FeatureTypeName, "feature type");
    t.Nest(PLACEDB_MEMBER(O, orb), OrbOptions::Table());
    t.Nest(PLACEDB_MEMBER(O, surf), SurfOptions::Table());
    t.Number("upscale_below", PLACEDB_MEMBER(O, upscale_below), OptionRange::Closed(0, 4096),
             "small frames: upscale images whose shorter side is below this for extraction "
             "(0: never)");
    t.Number("upscaled_fast_threshold", PLACEDB_MEMBER(O, upscaled_fast_threshold),
             OptionRange::Closed(0, 255),
             "small frames: ORB's FAST threshold on images upscaled 2x or more (0: "
             "orb_fast_threshold)")
        .absent = int64_t{0};
    t.Bool("clahe", PLACEDB_MEMBER(O, clahe),
           "local features: contrast-equalise the grey frame (CLAHE) before detection, for the "
           "map and its queries alike")
        .absent = false;
    t.Nest(PLACEDB_MEMBER(O, whole_image), WholeImageOptions::Table());
    return t;
  }();
  return table;
}

std::string ExtractorOptions::Check() const { return Table().Check(*this); }

}  // namespace placedb
