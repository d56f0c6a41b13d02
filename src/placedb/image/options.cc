// The option table of the feature-rich crop (util/option_table.h).
#include "placedb/image/crop_options.h"
#include "placedb/util/option_table.h"

namespace placedb {

const OptionTable<CropOptions>& CropOptions::Table() {
  static const OptionTable<CropOptions> table = [] {
    using O = CropOptions;
    OptionTable<O> t("crop options");
    t.Number("crop_sigma", PLACEDB_MEMBER(O, smooth_sigma), OptionRange::Closed(0, 50),
             "chroma crop: smoothing sigma, px");
    t.Number("crop_percentile", PLACEDB_MEMBER(O, percentile), OptionRange::Closed(0, 99.9),
             "chroma crop: pixels above this percentile of a channel are concentrated");
    t.Number("crop_padding", PLACEDB_MEMBER(O, padding), OptionRange::Closed(0, 4096),
             "chroma crop: padding around a region, px");
    t.Number("crop_min_fast", PLACEDB_MEMBER(O, min_fast_keypoints),
             OptionRange::Closed(0, 100000), "chroma crop: FAST corners a crop needs (the paper's 15)");
    t.Number("crop_fast_threshold", PLACEDB_MEMBER(O, fast_threshold), OptionRange::Closed(1, 255),
             "chroma crop: FAST threshold of the count");
    t.Bool("crop_fast_nonmax", PLACEDB_MEMBER(O, fast_nonmax),
           "chroma crop: FAST non-maximum suppression");
    t.Number("crop_min_region", PLACEDB_MEMBER(O, min_region_pixels), OptionRange::Closed(1, 1e8),
             "chroma crop: smallest region that can become a crop, pixels");
    return t;
  }();
  return table;
}

std::string CropOptions::Check() const { return Table().Check(*this); }

}  // namespace placedb
