// The option tables of reading images and TUM folders (util/option_table.h).
#include "placedb/dataset/frame.h"
#include "placedb/dataset/tum.h"
#include "placedb/util/option_table.h"

namespace placedb {

const OptionTable<ImageReadOptions>& ImageReadOptions::Table() {
  static const OptionTable<ImageReadOptions> table = [] {
    using O = ImageReadOptions;
    OptionTable<O> t("image read options");
    // 2^30 is OpenCV's own limit.
    t.Number("max_image_pixels", PLACEDB_MEMBER(O, max_pixels),
             OptionRange::Closed(1, 1073741824.0),
             "largest image decoded, width x height pixels as its header declares them (checked "
             "before decoding; also bounds `frame_size`)",
             kCallers);
    return t;
  }();
  return table;
}

std::string ImageReadOptions::Check() const { return Table().Check(*this); }

const OptionTable<TumOptions>& TumOptions::Table() {
  static const OptionTable<TumOptions> table = [] {
    using O = TumOptions;
    OptionTable<O> t("TUM options");
    t.Number("max_time_diff", PLACEDB_MEMBER(O, max_time_difference), OptionRange::Closed(0, 3600),
             "TUM: largest |dt| between a frame and its ground-truth pose, seconds", kCallers);
    t.String("tum_rgb_list", PLACEDB_MEMBER(O, rgb_list), "TUM: image list inside the folder",
             kCallers);
    t.String("tum_groundtruth", PLACEDB_MEMBER(O, groundtruth),
             "TUM: ground-truth file inside the folder", kCallers);
    t.Rule([](const O& o) -> std::string {
      if (o.rgb_list.empty()) return "`tum_rgb_list` must not be empty";
      if (o.groundtruth.empty()) return "`tum_groundtruth` must not be empty";
      return "";
    });
    return t;
  }();
  return table;
}

std::string TumOptions::Check() const { return Table().Check(*this); }

}  // namespace placedb
