// The option table of opening a database (util/option_table.h).
#include <climits>
#include <cmath>
#include <cstdlib>

#include "placedb/session/place_database.h"
#include "placedb/util/check.h"
#include "placedb/util/option_table.h"

namespace placedb {
namespace {

namespace oi = option_table_internal;

// A whole number in [lo, hi] from one item of a list ("12"), or
// InvalidArgument naming `name`.
int64_t WholeNumber(const std::string& item, const std::string& name, int64_t lo, int64_t hi) {
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(item.c_str(), &end, 10);
  if (item.empty() || end != item.c_str() + item.size() || errno == ERANGE || v < lo || v > hi) {
    PLACEDB_THROW_INVALID("`", name, "`: '", item, "' is not a whole number in [", lo, ", ", hi,
                          "]");
  }
  return v;
}

void SetPartition(OpenOptions& o, const OptionValue& v) {
  int64_t part = 0, parts = 0;
  if (const std::string* text = std::get_if<std::string>(&v)) {
    if (text->empty()) {
      if (o.subset.kind == KeyframeSubset::Kind::kPartition) o.subset = KeyframeSubset::All();
      return;
    }
    const size_t slash = text->find('/');
    if (slash == std::string::npos) {
      PLACEDB_THROW_INVALID("`partition` takes I/N, e.g. 0/3 (got '", *text, "')");
    }
    parts = WholeNumber(text->substr(slash + 1), "partition", 1, 4096);
    part = WholeNumber(text->substr(0, slash), "partition", 0, parts - 1);
  } else {
    const std::vector<double> n = oi::ToNumbers(v, "partition");
    if (n.empty()) {
      if (o.subset.kind == KeyframeSubset::Kind::kPartition) o.subset = KeyframeSubset::All();
      return;
    }
    if (n.size() != 2 || n[0] != std::floor(n[0]) || n[1] != std::floor(n[1]) || !(n[1] >= 1) ||
        !(n[1] <= 4096) || !(n[0] >= 0) || !(n[0] < n[1])) {
      PLACEDB_THROW_INVALID("`partition` takes (I, N): N in [1, 4096], I in [0, N), whole numbers");
    }
    part = static_cast<int64_t>(n[0]);
    parts = static_cast<int64_t>(n[1]);
  }
  if (o.subset.kind == KeyframeSubset::Kind::kIds) {
    PLACEDB_THROW_INVALID("give `partition` or `keyframes`, not both");
  }
  o.subset =
      KeyframeSubset::Partition(static_cast<int>(part), static_cast<int>(parts), o.subset.scheme);
}

void SetKeyframes(OpenOptions& o, const OptionValue& v) {
  std::vector<int32_t> ids;
  for (const std::string& item : oi::ToList(v, "keyframes")) {
    ids.push_back(static_cast<int32_t>(WholeNumber(item, "keyframes", 1, INT32_MAX)));
  }
  if (ids.empty()) {
    if (o.subset.kind == KeyframeSubset::Kind::kIds) o.subset = KeyframeSubset::All();
    return;
  }
  if (o.subset.kind == KeyframeSubset::Kind::kPartition) {
    PLACEDB_THROW_INVALID("give `partition` or `keyframes`, not both");
  }
  const PartitionScheme scheme = o.subset.scheme;
  o.subset = KeyframeSubset::Ids(std::move(ids));
  o.subset.scheme = scheme;
}

}  // namespace

const OptionTable<OpenOptions>& OpenOptions::Table() {
  static const OptionTable<OpenOptions> table = [] {
    using O = OpenOptions;
    OptionTable<O> t("open options");
    OptionField partition;
    partition.name = "partition";
    partition.member = "subset";
    partition.kind = OptionKind::kText;
    partition.help = "open only partition I of N of the keyframes, e.g. 0/3; '' (default): all";
    partition.range = "I/N with N in [1, 4096], I in [0, N)";
    partition.surfaces = kCallers;
    t.Custom(
        &O::subset, partition,
        [](const O& o) -> OptionValue {
          if (o.subset.kind != KeyframeSubset::Kind::kPartition) return std::string();
          return std::to_string(o.subset.part) + "/" + std::to_string(o.subset.num_parts);
        },
        SetPartition,
        [](const O& o) -> std::string {
          if (o.subset.kind != KeyframeSubset::Kind::kPartition) return "";
          const std::string reason = o.subset.Check();
          return reason.empty() ? "" : "`partition`: " + reason;
        });
    OptionField scheme;
    scheme.name = "partition_scheme";
    scheme.member = "subset.scheme";
    scheme.kind = OptionKind::kChoice;
    scheme.choices = {"contiguous", "interleaved"};
    scheme.help = "partitions as contiguous ranges or interleaved indices";
    scheme.range = "contiguous or interleaved";
    scheme.surfaces = kCallers;
    t.Custom(
        &O::subset, scheme,
        [](const O& o) -> OptionValue { return std::string(PartitionSchemeName(o.subset.scheme)); },
        [](O& o, const OptionValue& v) {
          o.subset.scheme = ParsePartitionScheme(oi::ToString(v, "partition_scheme"));
        });
    OptionField keyframes;
    keyframes.name = "keyframes";
    keyframes.member = "subset.ids";
    keyframes.kind = OptionKind::kList;
    keyframes.help = "open only these keyframe ids, e.g. 3,4,17; '' (default): all";
    keyframes.range = "ids present in the database";
    keyframes.surfaces = kCallers;
    t.Custom(
        &O::subset, keyframes,
        [](const O& o) -> OptionValue {
          std::vector<std::string> ids;
          if (o.subset.kind == KeyframeSubset::Kind::kIds) {
            for (const int32_t id : o.subset.ids) ids.push_back(std::to_string(id));
          }
          return ids;
        },
        SetKeyframes,
        [](const O& o) -> std::string {
          if (o.subset.kind == KeyframeSubset::Kind::kIds && o.subset.ids.empty())
            return "`keyframes` is an empty list";
          return "";
        });
    OptionField features;
    features.name = "expected_features";
    features.flag = "--features";
    features.member = "expected_features";
    features.kind = OptionKind::kChoice;
    features.choices = {"orb", "surf"};
    features.help = "the feature type the database must have ('': any)";
    features.range = "orb or surf";
    features.surfaces = kCallers;
    t.Custom(
        &O::expected_features, features,
        [](const O& o) -> OptionValue {
          return std::string(o.expected_features ? FeatureTypeName(*o.expected_features) : "");
        },
        [](O& o, const OptionValue& v) {
          if (const auto* none = std::get_if<std::vector<double>>(&v); none && none->empty()) {
            o.expected_features.reset();
            return;
          }
          const std::string name = oi::ToString(v, "expected_features");
          if (name.empty()) {
            o.expected_features.reset();
          } else {
            o.expected_features = ParseFeatureType(name);
          }
        });
    t.Number("threads", PLACEDB_MEMBER(O, threads), OptionRange::Closed(0, 1024),
             "threads each query uses for matching and verification (0: one per core)", kCallers);
    t.Nest(PLACEDB_MEMBER(O, clusters), ClusterOptions::Table(), kCallers);
    // Programs choose it (the voter, the extractor node), not their users.
    t.Bool("keyframe_table", PLACEDB_MEMBER(O, keyframe_table),
           "open only the keyframe table (ids, poses, sources): no queries, no changes",
           BoolFlag::kSwitch, kPython);
    t.Bool("prefetch", PLACEDB_MEMBER(O, prefetch),
           "read the database files into the page cache in the background after the open, then "
           "check the index and the keyframes' features",
           BoolFlag::kNegatable, kCallers);
    t.Bool("read_features", PLACEDB_MEMBER(O, read_features),
           "queries read the examined keyframes' features from the file instead of mapping "
           "them: resident memory stays near the index's, at a read per keyframe",
           BoolFlag::kSwitch, kCallers);
    t.Number("read_features_above_mb", PLACEDB_MEMBER(O, read_features_above_mb),
             OptionRange::Closed(0, 1048576),
             "queries read the examined keyframes' features, as read_features, when the keyframe "
             "file is larger than this (MiB; 0: size never decides)",
             kCallers);
    t.Number("resident_limit_mb", PLACEDB_MEMBER(O, resident_limit_mb),
             OptionRange::Closed(0, 1048576),
             "above this file-backed resident memory (MiB) after a query, let go of the "
             "database files' resident pages (0: never)",
             kCallers);
    return t;
  }();
  return table;
}

std::string OpenOptions::Check() const { return Table().Check(*this); }

const OptionTable<AddOptions>& AddOptions::Table() {
  static const OptionTable<AddOptions> table = [] {
    using O = AddOptions;
    OptionTable<O> t("add options");
    t.Number("id_offset", PLACEDB_MEMBER(O, id_offset), OptionRange::RightOpen(0, 2147483648.0),
             "id of the first frame given; the k-th gets id_offset + k - 1 (0: the ids after the "
             "largest the database ever held)",
             kCommandLine);
    t.Bool("ids_from_names", PLACEDB_MEMBER(O, ids_from_names),
           "each frame's id is its file name's number (042.jpg: 42); other names are refused",
           BoolFlag::kSwitch, kCommandLine);
    t.Bool("skip_existing", PLACEDB_MEMBER(O, skip_existing),
           "leave out frames already in the database: same source path and file content "
           "(default: an error); a known path with new content is added",
           BoolFlag::kSwitch, kCommandLine);
    t.Rule([](const O& o) -> std::string {
      if (o.ids_from_names && o.id_offset != 0)
        return "give `id_offset` or `ids_from_names`, not both";
      return "";
    });
    return t;
  }();
  return table;
}

std::string AddOptions::Check() const { return Table().Check(*this); }

}  // namespace placedb
