// The option table of a build, and the build settings a manifest keeps
// (util/option_table.h, util/option_json.h).
#include "placedb/builder/build.h"
#include "placedb/builder/builder.h"
#include "placedb/util/check.h"
#include "placedb/util/json_reader.h"
#include "placedb/util/option_json.h"
#include "placedb/util/option_table.h"

namespace placedb {

const OptionTable<BuildOptions>& BuildOptions::Table() {
  static const OptionTable<BuildOptions> table = [] {
    using O = BuildOptions;
    OptionTable<O> t("build settings");
    t.Nest(PLACEDB_MEMBER(O, features), ExtractorOptions::Table());
    t.Number(
         "stored_features", PLACEDB_MEMBER(O, stored_features), OptionRange::Closed(0, 100000),
         "most features a keyframe keeps, those tracked first (track_neighbours), spread over its "
         "image (0: all; queries keep all)")
        .absent = int64_t{0};  // manifests written before the budget
    t.Number("track_neighbours", PLACEDB_MEMBER(O, track_neighbours), OptionRange::Closed(0, 32),
             "stored_features: first the features matched in this many nearest keyframes (by "
             "position when every frame has a pose, else in order), then spread (0: spread alone)")
        .absent = int64_t{0};  // manifests written before tracked budgets
    t.Choice("crop", PLACEDB_MEMBER(O, crop), {CropMode::kNone, CropMode::kChroma}, ParseCropMode,
             CropModeName, "none, or chroma: the paper's feature-rich crop");
    t.Nest(PLACEDB_MEMBER(O, crop_options), CropOptions::Table());
    t.Number("resize", PLACEDB_MEMBER(O, resize), OptionRange::OneOf({1, 4, 16}),
             "stored image area divisor");
    t.Bool("extract_in_context", PLACEDB_MEMBER(O, extract_in_context),
           "crop: extract features on the whole frame and keep those inside the crop (false: on "
           "the stored crop alone)");
    t.Bool("store_images", PLACEDB_MEMBER(O, store_images),
           "keep the stored images (PNG) in the database (the command line's --no-images: do not)",
           BoolFlag::kInverted)
        .flag = "--no-images";
    t.Number("png_compression", PLACEDB_MEMBER(O, png_compression), OptionRange::Closed(0, 9),
             "PNG level of the stored images");
    t.Choice("index", PLACEDB_MEMBER(O, index), {IndexKind::kNone, IndexKind::kBow}, ParseIndexKind,
             IndexKindName,
             "retrieval index: none, or bow (a vocabulary and an inverted file, for search bow)")
        .absent = std::string("none");  // manifests written before bag-of-words indexes
    t.Nest(PLACEDB_MEMBER(O, vocabulary), VocabularyOptions::Table());
    t.String("vocabulary", PLACEDB_MEMBER(O, vocabulary_file),
             "bow: use this vocabulary file (e.g. another database's vocabulary.bin) instead of "
             "training one ('': train)");
    t.Nest(PLACEDB_MEMBER(O, bow), BowIndexOptions::Table());
    t.Number("threads", PLACEDB_MEMBER(O, threads), OptionRange::Closed(0, 1024),
             "worker threads (0: one per core)", kCallers);
    t.Bool("strict", PLACEDB_MEMBER(O, strict), "fail on an unreadable image (default: skip it)",
           BoolFlag::kSwitch, kCallers);
    // The command line's --quiet turns it off.
    t.Bool("progress", PLACEDB_MEMBER(O, progress), "draw a progress bar (only on a terminal)",
           BoolFlag::kValue, kPython);
    t.Bool("overwrite", PLACEDB_MEMBER(O, overwrite), "replace an existing database",
           BoolFlag::kSwitch, kCallers);
    // Manifests written before bag-of-words indexes, and those of databases
    // built without one, lack the vocabulary's settings: they mean nothing
    // there, and read as the defaults.
    const O defaults;
    for (const OptionTableBase::Entry& e : VocabularyOptions::Table().entries()) {
      t.Modify(e.field.name).absent = e.get(&defaults.vocabulary);
    }
    t.Modify("vocabulary").absent = std::string();
    t.Modify("direct_level").absent = int64_t{BowIndexOptions().direct_level};
    t.Rule([](const O& o) -> std::string {
      if (o.index == IndexKind::kBow && o.vocabulary_file.empty() &&
          o.bow.direct_level > o.vocabulary.depth) {
        return "`direct_level` must be at most `vocabulary_depth` (" +
               std::to_string(o.vocabulary.depth) + ")";
      }
      return "";
    });
    return t;
  }();
  return table;
}

std::string BuildOptions::Check() const { return Table().Check(*this); }

nlohmann::json BuildSettingsToJson(const BuildOptions& options) {
  return OptionsToJson(options, kManifest);
}

BuildOptions BuildOptionsFromManifest(const nlohmann::json& manifest, const std::string& dir) {
  const JsonReader m(manifest, dir + "/manifest.json", JsonOrigin::kDatabaseFile);
  BuildOptions o;
  OptionsFromJson(m.Child("settings"), &o, kManifest);
  const std::string reason = o.Check();
  if (!reason.empty()) PLACEDB_THROW_CORRUPT(dir, "/manifest.json: settings: ", reason);
  return o;
}

}  // namespace placedb
