// The option table of our SURF (util/option_table.h).
#include "placedb/feature/surf/surf_options.h"
#include "placedb/util/option_table.h"

namespace placedb {

const OptionTable<SurfOptions>& SurfOptions::Table() {
  static const OptionTable<SurfOptions> table = [] {
    using O = SurfOptions;
    OptionTable<O> t("SURF options");
    t.Number("surf_hessian", PLACEDB_MEMBER(O, hessian_threshold), OptionRange::Closed(0, 1e6),
             "SURF: Hessian threshold");
    t.Number("surf_octaves", PLACEDB_MEMBER(O, num_octaves), OptionRange::Closed(1, 8),
             "SURF: octaves");
    t.Number("surf_layers", PLACEDB_MEMBER(O, num_octave_layers),
             OptionRange::Closed(1, 8), "SURF: layers per octave");
    t.Bool("surf_extended", PLACEDB_MEMBER(O, extended), "SURF: 128-d descriptors",
           BoolFlag::kSwitch);
    t.Bool("surf_upright", PLACEDB_MEMBER(O, upright), "SURF: U-SURF, no orientation",
           BoolFlag::kSwitch);
    t.Number("surf_max_features", PLACEDB_MEMBER(O, max_features), OptionRange::Closed(0, 1e6),
             "SURF: most keypoints (0: all)");
    return t;
  }();
  return table;
}

std::string SurfOptions::Check() const { return Table().Check(*this); }

}  // namespace placedb
