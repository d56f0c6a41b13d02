#include "placedb/python/options.h"

#include <type_traits>
#include <utility>

#include "placedb/python/conversions.h"
#include "placedb/util/check.h"

namespace placedb {
namespace python {
namespace {

// A field of an options struct, for both const and non-const access.
#define PLACEDB_FIELD(member) \
  [](auto& o) -> auto& { return o.member; }

// The type of the field `F` accesses (checked against the option's kind).
template <typename O, typename F>
using FieldType = std::decay_t<decltype(std::declval<F>()(std::declval<O&>()))>;

template <typename O, typename F>
OptionSpec<O> Int(const char* name, const char* help, F field) {
  static_assert(std::is_same_v<FieldType<O, F>, int>, "Int: the field is not a int");
  return {name, help, [field](O& o, py::handle v, const std::string& n) { field(o) = ToInt(v, n); },
          [field](const O& o) -> py::object { return py::int_(field(o)); }};
}

template <typename O, typename F>
OptionSpec<O> Uint64(const char* name, const char* help, F field) {
  static_assert(std::is_same_v<FieldType<O, F>, uint64_t>, "Uint64: the field is not a uint64_t");
  return {name, help,
          [field](O& o, py::handle v, const std::string& n) { field(o) = ToUint64(v, n); },
          [field](const O& o) -> py::object { return py::int_(field(o)); }};
}

template <typename O, typename F>
OptionSpec<O> Double(const char* name, const char* help, F field) {
  static_assert(std::is_same_v<FieldType<O, F>, double>, "Double: the field is not a double");
  return {name, help,
          [field](O& o, py::handle v, const std::string& n) { field(o) = ToDouble(v, n); },
          [field](const O& o) -> py::object { return py::float_(field(o)); }};
}

template <typename O, typename F>
OptionSpec<O> Bool(const char* name, const char* help, F field) {
  static_assert(std::is_same_v<FieldType<O, F>, bool>, "Bool: the field is not a bool");
  return {name, help,
          [field](O& o, py::handle v, const std::string& n) { field(o) = ToBool(v, n); },
          [field](const O& o) -> py::object { return py::bool_(field(o)); }};
}

template <typename O, typename F>
OptionSpec<O> Path(const char* name, const char* help, F field) {
  static_assert(std::is_same_v<FieldType<O, F>, std::string>,
                "Path: the field is not a std::string");
  return {name, help,
          [field](O& o, py::handle v, const std::string& n) { field(o) = ToPath(v, n); },
          [field](const O& o) -> py::object { return py::str(field(o)); }};
}

// A named choice, parsed and named by the library's own functions.
template <typename O, typename F, typename Parse, typename Name>
OptionSpec<O> Choice(const char* name, const char* help, F field, Parse parse, Name to_name) {
  return {name, help,
          [field, parse](O& o, py::handle v, const std::string& n) {
            field(o) = parse(ToString(v, n));
          },
          [field, to_name](const O& o) -> py::object { return py::str(to_name(field(o))); }};
}

template <typename O>
const OptionSpec<O>* FindSpec(const std::vector<OptionSpec<O>>& specs, const std::string& name) {
  for (const auto& s : specs) {
    if (name == s.name) return &s;
  }
  return nullptr;
}

template <typename O>
std::string Names(const std::vector<OptionSpec<O>>& specs) {
  std::string out;
  for (const auto& s : specs) out += (out.empty() ? "" : ", ") + std::string(s.name);
  return out;
}

template <typename O>
O Apply(const std::vector<OptionSpec<O>>& specs, const py::kwargs& kwargs, O options,
        const char* what) {
  for (const auto& item : kwargs) {
    const std::string name = py::str(item.first).cast<std::string>();
    const OptionSpec<O>* spec = FindSpec(specs, name);
    if (spec == nullptr) {
      throw py::type_error("unexpected keyword argument '" + name + "' (" + what +
                           " are: " + Names(specs) + ")");
    }
    spec->set(options, item.second, name);
  }
  const std::string reason = options.Check();
  if (!reason.empty()) PLACEDB_THROW_INVALID("invalid ", what, ": ", reason);
  return options;
}

}  // namespace

const std::vector<OptionSpec<QueryOptions>>& QuerySpecs() {
  using O = QueryOptions;
  static const std::vector<OptionSpec<O>> specs = {
      Int<O>("top_k", "length of the ranked list [1, 10000]", PLACEDB_FIELD(top_k)),
      Choice<O>("search",
                "retrieve stage: 'exhaustive' (every keyframe), 'bow' (bag-of-words candidates; "
                "needs a database built with index='bow') or 'cluster' (the prior's "
                "spatial-locality clusters first, then the rest when the answer is weak)",
                PLACEDB_FIELD(retrieval.method), ParseRetrievalMethod, RetrievalMethodName),
      Int<O>("bow_candidates", "bow: keyframes scored best by bag of words [1, 100000]",
             PLACEDB_FIELD(retrieval.bow_candidates)),
      Int<O>("guided_candidates",
             "bow: of those, the ones with the most guided matches (same vocabulary node) are "
             "matched in full; 0 = all [0, 100000]",
             PLACEDB_FIELD(retrieval.guided_candidates)),
      Int<O>("cluster_hops", "cluster: neighbour clusters searched around the prior's [0, 64]",
             PLACEDB_FIELD(retrieval.cluster_hops)),
      Double<O>("cluster_fallback_score",
                "cluster: a local best score below this searches the rest of the database "
                "(0: min_score) [0, 100000]",
                PLACEDB_FIELD(retrieval.cluster_fallback_score)),
      Int<O>("prior_keyframe",
             "cluster: id of a keyframe near the query (e.g. the last answer); 0: none [0, 2^31)",
             PLACEDB_FIELD(prior.keyframe_id)),
      {"prior_pose",
       "cluster: where the robot probably is, a placedb.Pose or ((x, y, z), (qx, qy, qz, qw)) in "
       "the map frame; None: none (prior_keyframe wins when both are set)",
       [](O& o, py::handle v, const std::string& n) {
         if (v.is_none()) {
           o.prior.pose.reset();
         } else {
           o.prior.pose = ToPose(v, n);
         }
       },
       [](const O& o) -> py::object {
         if (!o.prior.pose) return py::none();
         return py::cast(*o.prior.pose);
       }},
      Double<O>("deadline_ms",
                "time budget of retrieve + match + verify, ms; candidates are examined best "
                "first until it runs out (0: none) [0, 1e7]",
                PLACEDB_FIELD(deadline_ms)),
      Double<O>("ratio", "Lowe's ratio test threshold (0, 1]", PLACEDB_FIELD(match.ratio)),
      Int<O>("max_hamming", "ORB: largest Hamming distance of a match (0: no limit) [0, 256]",
             PLACEDB_FIELD(match.max_hamming)),
      Double<O>("max_l2", "SURF: largest L2 distance of a match (0: no limit) [0, 2]",
                PLACEDB_FIELD(match.max_l2)),
      Bool<O>("laplacian_sign", "SURF: never match opposite Laplacian signs",
              PLACEDB_FIELD(match.use_laplacian_sign)),
      Bool<O>("one_to_one", "a keyframe descriptor keeps only its closest query match",
              PLACEDB_FIELD(match.one_to_one)),
      Bool<O>("cross_check",
              "sparse-keyframe guard: matches must be mutual and pass the ratio test among the "
              "query's descriptors too",
              PLACEDB_FIELD(match.cross_check)),
      Int<O>("min_matches", "fewest matches for a keyframe to be ranked [1, 100000]",
             PLACEDB_FIELD(min_matches)),
      Bool<O>("verify", "verify stage: RANSAC (USAC) on the best candidates, inliers are the score",
              PLACEDB_FIELD(verify.enabled)),
      Choice<O>("verify_model", "'fundamental' or 'homography'", PLACEDB_FIELD(verify.model),
                ParseGeometricModel, GeometricModelName),
      Int<O>("verify_candidates", "keyframes verified (the best by matches) [1, 1000]",
             PLACEDB_FIELD(verify.num_candidates)),
      Double<O>("verify_error", "largest inlier error, px of the query image (0, 100]",
                PLACEDB_FIELD(verify.max_error_px)),
      Double<O>("verify_confidence", "RANSAC confidence [0.5, 1)",
                PLACEDB_FIELD(verify.confidence)),
      Int<O>("verify_iterations", "RANSAC iterations at most [1, 100000]",
             PLACEDB_FIELD(verify.max_iterations)),
      Int<O>("verify_seed", "RANSAC seed [0, 2^31)", PLACEDB_FIELD(verify.seed)),
      Double<O>("min_score",
                "decide stage: the best keyframe is the answer when its score (inliers when "
                "verified, else matches) is at least this; else 'no match' [0, 100000]",
                PLACEDB_FIELD(min_score)),
  };
  return specs;
}

const std::vector<OptionSpec<BuildOptions>>& BuildSpecs() {
  using O = BuildOptions;
  static const std::vector<OptionSpec<O>> specs = {
      Choice<O>("features", "feature type: 'orb' or 'surf'", PLACEDB_FIELD(features.type),
                ParseFeatureType, FeatureTypeName),
      Choice<O>("crop", "'none', or 'chroma': the paper's feature-rich crop", PLACEDB_FIELD(crop),
                ParseCropMode, CropModeName),
      Int<O>("resize", "stored image area divisor: 1, 4 or 16", PLACEDB_FIELD(resize)),
      Choice<O>("index",
                "retrieval index: 'none', or 'bow' (a vocabulary and an inverted file, for "
                "search='bow')",
                PLACEDB_FIELD(index), ParseIndexKind, IndexKindName),
      Bool<O>("overwrite", "replace an existing database at out", PLACEDB_FIELD(overwrite)),
      Int<O>("threads", "worker threads (0: one per core) [0, 1024]", PLACEDB_FIELD(threads)),
      Bool<O>("progress", "draw a progress bar (only on a terminal)", PLACEDB_FIELD(progress)),
      Bool<O>("strict", "fail on an unreadable image (default: skip it)", PLACEDB_FIELD(strict)),
      Bool<O>("store_images", "keep the stored images (PNG) in the database",
              PLACEDB_FIELD(store_images)),
      Bool<O>("extract_in_context",
              "crop: extract features on the whole frame and keep those inside the crop "
              "(False: on the stored crop alone)",
              PLACEDB_FIELD(extract_in_context)),
      Int<O>("png_compression", "PNG level [0, 9]", PLACEDB_FIELD(png_compression)),
      Path<O>("vocabulary",
              "bow: use this vocabulary file (e.g. another database's vocabulary.bin) instead "
              "of training one ('': train)",
              PLACEDB_FIELD(vocabulary_file)),
      Int<O>("vocabulary_branching", "bow: children per node [2, 64]",
             PLACEDB_FIELD(vocabulary.branching)),
      Int<O>("vocabulary_depth", "bow: levels of the vocabulary tree [1, 8]",
             PLACEDB_FIELD(vocabulary.depth)),
      Int<O>("vocabulary_iterations", "bow: clustering iterations per node [1, 100]",
             PLACEDB_FIELD(vocabulary.iterations)),
      Int<O>("vocabulary_sample", "bow: descriptors sampled for training [1000, 100000000]",
             PLACEDB_FIELD(vocabulary.max_training_descriptors)),
      Uint64<O>("vocabulary_seed", "bow: training seed", PLACEDB_FIELD(vocabulary.seed)),
      Int<O>("direct_level", "bow: vocabulary level of the direct index [0, depth]",
             PLACEDB_FIELD(bow.direct_level)),
      Int<O>("orb_max_features", "ORB: most keypoints per image [1, 100000]",
             PLACEDB_FIELD(features.orb.max_features)),
      Double<O>("orb_scale_factor", "ORB: pyramid scale factor (1, 4]",
                PLACEDB_FIELD(features.orb.scale_factor)),
      Int<O>("orb_levels", "ORB: pyramid levels [1, 32]", PLACEDB_FIELD(features.orb.num_levels)),
      Int<O>("orb_fast_threshold", "ORB: FAST threshold [1, 255]",
             PLACEDB_FIELD(features.orb.fast_threshold)),
      Int<O>("orb_edge_threshold", "ORB: border without features, px [0, 512]",
             PLACEDB_FIELD(features.orb.edge_threshold)),
      Int<O>("orb_patch_size", "ORB: BRIEF patch size, px [2, 512]",
             PLACEDB_FIELD(features.orb.patch_size)),
      Double<O>("surf_hessian", "SURF: Hessian threshold [0, 1e6]",
                PLACEDB_FIELD(features.surf.hessian_threshold)),
      Int<O>("surf_octaves", "SURF: octaves [1, 8]", PLACEDB_FIELD(features.surf.num_octaves)),
      Int<O>("surf_layers", "SURF: layers per octave [1, 8]",
             PLACEDB_FIELD(features.surf.num_octave_layers)),
      Bool<O>("surf_extended", "SURF: 128-d descriptors", PLACEDB_FIELD(features.surf.extended)),
      Bool<O>("surf_upright", "SURF: U-SURF, no orientation", PLACEDB_FIELD(features.surf.upright)),
      Int<O>("surf_max_features", "SURF: most keypoints (0: all) [0, 1000000]",
             PLACEDB_FIELD(features.surf.max_features)),
      Int<O>("upscale_below",
             "small frames: upscale images whose shorter side is below this for extraction "
             "(0: never) [0, 4096]",
             PLACEDB_FIELD(features.upscale_below)),
      Double<O>("crop_percentile",
                "chroma crop: pixels above this percentile of a channel are concentrated "
                "[0, 99.9]",
                PLACEDB_FIELD(crop_options.percentile)),
      Double<O>("crop_sigma", "chroma crop: smoothing sigma, px [0, 50]",
                PLACEDB_FIELD(crop_options.smooth_sigma)),
      Int<O>("crop_padding", "chroma crop: padding around a region, px [0, 4096]",
             PLACEDB_FIELD(crop_options.padding)),
      Int<O>("crop_min_fast", "chroma crop: FAST corners a crop needs (the paper's 15) [0, 100000]",
             PLACEDB_FIELD(crop_options.min_fast_keypoints)),
      Int<O>("crop_fast_threshold", "chroma crop: FAST threshold of the count [1, 255]",
             PLACEDB_FIELD(crop_options.fast_threshold)),
      Bool<O>("crop_fast_nonmax", "chroma crop: FAST non-maximum suppression",
              PLACEDB_FIELD(crop_options.fast_nonmax)),
      Int<O>("crop_min_region", "chroma crop: smallest region that can become a crop, pixels",
             PLACEDB_FIELD(crop_options.min_region_pixels)),
  };
  return specs;
}

QueryOptions QueryOptionsFrom(const py::kwargs& kwargs, QueryOptions defaults) {
  return Apply(QuerySpecs(), kwargs, std::move(defaults), "query options");
}

BuildOptions BuildOptionsFrom(const py::kwargs& kwargs, BuildOptions defaults) {
  return Apply(BuildSpecs(), kwargs, std::move(defaults), "build settings");
}

}  // namespace python
}  // namespace placedb
