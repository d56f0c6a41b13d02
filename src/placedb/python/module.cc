// The placedb Python module: a thin client of the library, as the CLI is.
// Every call goes to the same C++ underneath (PlaceDatabase, BuildDatabase,
// Evaluate); this file only converts arguments and results, and releases
// the GIL while the library works.
#include <fmt/format.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "placedb/placedb.h"
#include "placedb/python/conversions.h"
#include "placedb/python/option_kwargs.h"

namespace placedb {
namespace python {
namespace {

namespace fs = std::filesystem;
using OptionalPath = std::optional<fs::path>;
using OptionalSize = std::optional<std::pair<int, int>>;

// Option structs are checked as the library checks them: InvalidArgument
// (placedb.InvalidArgumentError, a ValueError) naming the keyword.
template <typename T>
void CheckOptions(const T& options) {
  const std::string reason = options.Check();
  if (!reason.empty()) {
    throw InvalidArgument(std::string("invalid ") + T::Table().what() + ": " + reason,
                          "python/module.cc:" + std::to_string(__LINE__));
  }
}

// ---- errors ----------------------------------------------------------------
// placedb.Error and one subclass per ErrorKind, each also a built-in
// exception, so code that catches ValueError or FileNotFoundError keeps
// working. Module-level classes live as long as the interpreter: the
// references made here are never released.
struct ErrorClasses {
  PyObject* base = nullptr;
  PyObject* by_kind[5] = {};
};

ErrorClasses& Errors() {
  static ErrorClasses classes;
  return classes;
}

PyObject* NewErrorClass(py::module_& m, const char* name, PyObject* builtin, const char* doc) {
  const std::string qualified = std::string("placedb.") + name;
  PyObject* bases = PyTuple_Pack(2, Errors().base, builtin);
  if (bases == nullptr) throw py::error_already_set();
  PyObject* cls = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, bases, nullptr);
  Py_DECREF(bases);
  if (cls == nullptr) throw py::error_already_set();
  m.attr(name) = py::reinterpret_borrow<py::object>(cls);
  return cls;
}

void RegisterErrors(py::module_& m) {
  ErrorClasses& e = Errors();
  e.base = PyErr_NewExceptionWithDoc("placedb.Error", "Every error the placedb library raises.",
                                     PyExc_Exception, nullptr);
  if (e.base == nullptr) throw py::error_already_set();
  m.attr("Error") = py::reinterpret_borrow<py::object>(e.base);
  e.by_kind[static_cast<int>(ErrorKind::kInvalidArgument)] =
      NewErrorClass(m, "InvalidArgumentError", PyExc_ValueError, "A bad argument or option value.");
  e.by_kind[static_cast<int>(ErrorKind::kNotFound)] =
      NewErrorClass(m, "NotFoundError", PyExc_FileNotFoundError,
                    "A file or folder that does not exist: a database, an image, a list.");
  e.by_kind[static_cast<int>(ErrorKind::kCorruptDatabase)] = NewErrorClass(
      m, "CorruptDatabaseError", PyExc_ValueError,
      "A database, index or vocabulary file that is damaged, of another version or not "
      "placedb's.");
  e.by_kind[static_cast<int>(ErrorKind::kIo)] =
      NewErrorClass(m, "IoError", PyExc_OSError,
                    "The system failed a read or a write (permissions, a full disk).");
  e.by_kind[static_cast<int>(ErrorKind::kInternal)] =
      NewErrorClass(m, "InternalError", PyExc_RuntimeError, "A bug in placedb: please report it.");
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const Error& error) {
      PyObject* cls = Errors().by_kind[static_cast<int>(error.kind())];
      if (cls == nullptr) cls = Errors().base;
      // what(): the message with option names as keywords (an InternalError's
      // also says it is a bug, and where). Messages quote paths, which are
      // bytes: any that are not UTF-8 are kept as \xNN.
      const std::string what = error.what();
      PyObject* text = PyUnicode_DecodeUTF8(what.data(), static_cast<Py_ssize_t>(what.size()),
                                            "backslashreplace");
      PyObject* exc = text != nullptr ? PyObject_CallOneArg(cls, text) : nullptr;
      Py_XDECREF(text);
      if (exc == nullptr) return;  // the Python error of the failed call stands
      PyObject* where = PyUnicode_FromString(error.where().c_str());
      if (where == nullptr || PyObject_SetAttrString(exc, "where", where) != 0) PyErr_Clear();
      Py_XDECREF(where);
      PyErr_SetObject(cls, exc);
      Py_DECREF(exc);
    }
  });
}

// ---- results ---------------------------------------------------------------
std::string PoseRepr(const Pose& p) {
  const auto& t = p.translation;
  const auto& q = p.rotation;
  return fmt::format(
      "Pose(translation=({:.6g}, {:.6g}, {:.6g}), quaternion_xyzw=({:.6g}, {:.6g}, "
      "{:.6g}, {:.6g}))",
      t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
}

py::object OptionalPose(const std::optional<Pose>& pose) {
  return pose ? py::cast(*pose) : py::none();
}

std::string RankedRepr(const RankedKeyframe& k) {
  return fmt::format("RankedKeyframe(keyframe_id={}, score={:g}, num_matches={}, num_inliers={})",
                     k.keyframe_id, k.score, k.num_matches, k.num_inliers);
}

std::string ResultRepr(const QueryResult& r) {
  std::string answer;
  if (const RankedKeyframe* best = r.best()) {
    answer = fmt::format("keyframe {} (score {:g}", best->keyframe_id, best->score);
    answer += best->verified()
                  ? fmt::format(", {} inliers of {} matches)", best->num_inliers, best->num_matches)
                  : fmt::format(", {} matches)", best->num_matches);
  } else if (r.ranked.empty()) {
    answer = "no match (nothing ranked)";
  } else {
    answer = fmt::format("no match (best keyframe {} scores {:g})", r.ranked[0].keyframe_id,
                         r.ranked[0].score);
  }
  std::string ranked;
  for (const RankedKeyframe& k : r.ranked)
    ranked += (ranked.empty() ? "" : ", ") + std::to_string(k.keyframe_id);
  return fmt::format("<QueryResult {}; ranked [{}]; {} search, {:.0f}% of {} keyframes; {:.1f} ms>",
                     answer, ranked, r.search, 100.0 * r.coverage, r.num_keyframes,
                     r.times.total_ms);
}

// ---- the database session -------------------------------------------------
// A SequenceMatcher with the database its query() asks (kept alive by
// pybind11's keep_alive).
struct SequenceSession {
  SequenceSession(const PlaceDatabase& database, const SequenceOptions& options)
      : db(database), matcher(database.keyframes(), options) {}
  const PlaceDatabase& db;
  SequenceMatcher matcher;
};

std::unique_ptr<PlaceDatabase> OpenDatabase(const fs::path& dir, const py::kwargs& kwargs) {
  OpenOptions o;
  ApplyKwargs(kwargs, {Target(&o)}, "PlaceDatabase");
  CheckOptions(o);
  const std::string path = dir.string();
  py::gil_scoped_release release;
  return std::make_unique<PlaceDatabase>(PlaceDatabase::Open(path, o));
}

QueryOptions QueryOptionsFrom(const py::kwargs& kwargs, const char* function) {
  QueryOptions o;
  ApplyKwargs(kwargs, {Target(&o)}, function);
  CheckOptions(o);
  return o;
}

// A keyframe of an open database, copied out of it.
struct KeyframeInfo {
  Keyframe keyframe;
  std::string stored_image;
  size_t num_features = 0;
};

void RequireKeyframe(const PlaceDatabase& db, int32_t id) {
  if (!db.FindKeyframe(id))
    throw py::key_error(fmt::format("no keyframe with id {} in the database", id));
}

KeyframeInfo GetKeyframe(const PlaceDatabase& db, int32_t id) {
  const std::optional<Keyframe> found = db.FindKeyframe(id);
  if (!found) throw py::key_error(fmt::format("no keyframe with id {} in the database", id));
  KeyframeInfo k;
  k.keyframe = *found;
  k.stored_image = db.StoredImagePath(k.keyframe);
  k.num_features = db.KeyframeFeatures(id).size();
  return k;
}

int DescriptorColumns(const PlaceDatabase& db) {
  const int bytes = db.descriptor_bytes();
  return db.feature_type() == FeatureType::kOrb ? bytes : bytes / static_cast<int>(sizeof(float));
}

QueryResult QueryImage(const PlaceDatabase& db, const py::object& image, const py::kwargs& kwargs) {
  const QueryOptions options = QueryOptionsFrom(kwargs, "query");
  const ImageInput in = ToImage(image);
  py::gil_scoped_release release;
  return db.Query(in.mat, options);
}

QueryResult QueryFeatures(const PlaceDatabase& db, const py::object& keypoints,
                          const py::object& descriptors, const py::kwargs& kwargs) {
  const QueryOptions options = QueryOptionsFrom(kwargs, "query_features");
  const FeatureInput in = ToFeatures(keypoints, descriptors);
  py::gil_scoped_release release;
  return db.Query(in.set, options);
}

// Why keyframe `id` matched the image: PlaceDatabase::Explain as a dict of
// NumPy arrays.
py::dict ExplainImage(const PlaceDatabase& db, const py::object& image, int32_t id,
                      const py::kwargs& kwargs) {
  const QueryOptions options = QueryOptionsFrom(kwargs, "explain");
  const ImageInput in = ToImage(image);
  MatchDetail d;
  {
    py::gil_scoped_release release;
    d = db.Explain(db.Extract(in.mat), id, options);
  }
  const size_t n = d.matches.size();
  py::array_t<float> query_points({n, size_t{2}}), keyframe_points({n, size_t{2}});
  py::array_t<float> distances(n);
  py::array_t<bool> inliers(n);
  auto q = query_points.mutable_unchecked<2>();
  auto k = keyframe_points.mutable_unchecked<2>();
  auto dist = distances.mutable_unchecked<1>();
  auto in_mask = inliers.mutable_unchecked<1>();
  for (size_t i = 0; i < n; ++i) {
    const cv::DMatch& m = d.matches[i];
    const cv::Point2f a = d.query_keypoints[m.queryIdx].pt;
    const cv::Point2f b = d.keyframe_points[m.trainIdx];
    q(i, 0) = a.x;
    q(i, 1) = a.y;
    k(i, 0) = b.x;
    k(i, 1) = b.y;
    dist(i) = m.distance;
    in_mask(i) = d.verified && i < d.inliers.size() && d.inliers[i] != 0;
  }
  py::dict out;
  out["keyframe_id"] = d.keyframe_id;
  out["num_matches"] = n;
  out["verified"] = d.verified;
  out["num_inliers"] = d.verified ? d.num_inliers : -1;
  out["query_points"] = query_points;
  out["keyframe_points"] = keyframe_points;
  out["distances"] = distances;
  out["inliers"] = inliers;
  return out;
}

// The query beside keyframe `id` with the matches drawn (query --draw).
py::array DrawMatch(const PlaceDatabase& db, const py::object& image, int32_t id,
                    const std::string& caption, const py::kwargs& kwargs) {
  const QueryOptions options = QueryOptionsFrom(kwargs, "draw_match");
  const ImageInput in = ToImage(image);
  cv::Mat picture;
  {
    py::gil_scoped_release release;
    picture = DrawQueryMatch(db, in.mat, db.Extract(in.mat), id, options, caption);
  }
  return FromImage(picture);
}

py::tuple Extract(const PlaceDatabase& db, const py::object& image) {
  const ImageInput in = ToImage(image);
  FeatureSet features;
  {
    py::gil_scoped_release release;
    features = db.Extract(in.mat);
  }
  return FromFeatures(features, DescriptorColumns(db));
}

// ---- build, evaluate -------------------------------------------------------
py::dict Build(const fs::path& out, const py::kwargs& kwargs) {
  FrameSourceOptions source;
  BuildOptions options;
  options.progress = false;
  ApplyKwargs(kwargs, {Target(&source), Target(&options)}, "build");
  CheckOptions(source);  // before any work
  CheckOptions(options);
  const std::string out_dir = out.string();
  BuildReport report;
  {
    py::gil_scoped_release release;
    const std::vector<Frame> frames = ReadFrames(source);
    spdlog::info("building {} from {} frames ({} features, crop {}, resize 1/{})", out_dir,
                 frames.size(), FeatureTypeName(options.features.type), CropModeName(options.crop),
                 options.resize);
    report = BuildDatabase(frames, options, out_dir, DescribeFrameSource(source));
  }
  return FromJsonText(BuildReportJson(report, out_dir)).cast<py::dict>();
}

py::dict EvaluateDatabase(const PlaceDatabase& db, const py::kwargs& kwargs) {
  FrameSourceOptions source;
  GroundTruthOptions truth_options;
  EvalOptions options;
  options.progress = false;
  QueryOptions query;
  ApplyKwargs(kwargs, {Target(&source), Target(&truth_options), Target(&options), Target(&query)},
              "evaluate");
  CheckOptions(source);
  CheckOptions(truth_options);
  CheckOptions(options);
  CheckOptions(query);
  EvalReport report;
  {
    py::gil_scoped_release release;
    const std::vector<Frame> frames = ReadFrames(source);
    const GroundTruth truth = MakeGroundTruth(truth_options, source);
    report = Evaluate(db, frames, truth, options, query);
  }
  return FromJsonText(EvalReportJson(report)).cast<py::dict>();
}

// The database's frames default to the query source's, all of them
// (first=1, last=0); `database` (a dict of frame-source keywords) changes
// them, as --db-images/--db-tum/--db-first/--db-last do.
py::dict RunExperimentInto(const fs::path& out, const py::object& database, bool report,
                           const py::kwargs& kwargs) {
  FrameSourceOptions source;
  GroundTruthOptions truth_options;
  ExperimentOptions options;
  options.progress = false;
  ApplyKwargs(kwargs, {Target(&source), Target(&truth_options), Target(&options)}, "experiment");
  FrameSourceOptions db_source = source;
  db_source.first = 1;
  db_source.last = 0;
  if (!database.is_none()) {
    if (!py::isinstance<py::dict>(database))
      throw InvalidArgument(
          "`database` takes a dict of frame-source keywords (images, tum, first, "
          "last, ...)");
    py::kwargs db_kwargs;
    for (const auto& item : database.cast<py::dict>()) db_kwargs[item.first] = item.second;
    // A folder given for the database replaces the query source's.
    if (db_kwargs.contains("images") || db_kwargs.contains("tum")) {
      db_source.images.clear();
      db_source.tum.clear();
    }
    ApplyKwargs(db_kwargs, {Target(&db_source)}, "experiment(database=...)");
  }
  CheckOptions(source);
  CheckOptions(db_source);
  CheckOptions(truth_options);
  CheckOptions(options);
  const std::string out_dir = out.string();
  ExperimentSummary summary;
  std::string report_path;
  ExperimentData data;
  {
    py::gil_scoped_release release;
    data.queries = ReadFrames(source);
    data.queries_from = DescribeFrameSource(source);
    data.database = ReadFrames(db_source);
    data.database_from = DescribeFrameSource(db_source);
    const GroundTruth truth = MakeGroundTruth(truth_options, source);
    summary = RunExperiment(data, truth, options, out_dir);
    if (report) report_path = WriteExperimentReport(out_dir);
  }
  py::dict d;
  d["num_settings"] = summary.num_settings;
  d["num_reused"] = summary.num_reused;
  d["num_queries"] = summary.num_queries;
  d["num_database_frames"] = data.database.size();
  d["pictures"] = FsStrings(summary.pictures);
  d["results"] = FsString(summary.results);
  d["report"] = report ? py::object(FsString(report_path)) : py::object(py::none());
  return d;
}

py::array ReadImage(const fs::path& path, int64_t max_image_pixels) {
  Frame frame;
  frame.image_path = path.string();
  frame.read.max_pixels = max_image_pixels;
  CheckOptions(frame.read);
  cv::Mat image;
  {
    py::gil_scoped_release release;
    image = LoadFrameImage(frame);
  }
  if (image.empty()) ThrowUnreadableFrame(frame);
  return FromImage(image);
}

void SetLogLevel(const std::string& level) {
  static const std::vector<std::string> names = {"trace", "debug",    "info", "warn",
                                                 "error", "critical", "off"};
  if (std::find(names.begin(), names.end(), level) == names.end()) {
    throw InvalidArgument("unknown log level '" + level +
                          "' (expected trace, debug, info, warn, error, critical or off)");
  }
  spdlog::set_level(spdlog::level::from_str(level));
}

// ---- docstrings ------------------------------------------------------------
constexpr const char* kModuleDoc =
    R"doc(placedb: visual place recognition against a compact keyframe database.

The Python face of the placedb C++ library: the same code the `placedb`
command runs (PlaceDatabase, BuildDatabase, Evaluate), with NumPy arrays in
and Python objects out. Long calls (open, query, extract, build, evaluate,
read_image) release the GIL, and queries on one database may run from many
Python threads at once.

    import placedb
    placedb.build("office.db", images="data/rtabmap_loop/images", last=20)
    db = placedb.PlaceDatabase("office.db")
    image = placedb.read_image("data/rtabmap_loop/images/005.jpg")  # HxWx3 BGR uint8
    r = db.query(image, top_k=3)
    if r.matched:
        print(r.best.keyframe_id, r.best.score, r.best.pose)
    kp, desc = db.extract(image)          # Nx7 float32, Nx32 uint8 (ORB)
    same = db.query_features(kp, desc)    # the same answer as db.query(image)
    report = placedb.evaluate(db, images="data/rtabmap_loop/images",
                              truth="data/rtabmap_loop/ground_truth.csv", queries=10)

Images are uint8 NumPy arrays: HxW (gray), HxWx3 (BGR, OpenCV's order) or
HxWx4 (BGRA); other strides are copied, other dtypes are a ValueError.

Keypoints are Nx7 float32 rows (x, y, size, angle, response, octave,
class_id) as cv::KeyPoint holds them; Nx2 (x, y) is accepted too (the rest
get cv::KeyPoint's defaults; for SURF, class_id >= 0 is the positive sign of
the Laplacian, used by matching, so pass Nx7 or laplacian_sign=False).
Descriptors are NxD: uint8 with D = 32 for ORB, float32 with D = 64 or 128
for SURF (float64 is converted). extract() returns exactly this layout.

Errors are placedb.Error, one subclass per kind, each also the built-in
exception Python code already catches for it:
  InvalidArgumentError (a ValueError)    a bad argument or option value
  NotFoundError (a FileNotFoundError)    no database, image or list there
  CorruptDatabaseError (a ValueError)    a damaged or foreign database file
  IoError (an OSError)                   the system failed a read or write
  InternalError (a RuntimeError)         a bug in placedb: please report it
Each has the library's message (options named by their keywords) and
`where`, the source line that raised it. A value of the wrong Python type or
an unknown keyword is TypeError, an unknown keyframe id KeyError.

The library logs (spdlog) to the process's stderr; see set_log_level().
)doc";

constexpr const char* kQueryDoc =
    R"doc(Where was this image taken? retrieve -> match -> verify -> decide.

image: uint8 NumPy array, HxW (gray), HxWx3 (BGR) or HxWx4 (BGRA), a full
uncropped frame. Keyword options (all of QueryOptions; see
query_option_defaults()):

{}
Returns a QueryResult. Invalid options, images or features: ValueError.
)doc";

constexpr const char* kBuildDoc = R"doc(Builds a keyframe database at `out` (placedb build).

Frames: images= (a folder of images sorted by name, or a text file listing
image paths) or tum= (a TUM RGB-D folder: rgb.txt, groundtruth.txt), with
first/last (1-based ids, inclusive; last=0: to the end), frame_size=(W, H)
or "WxH" to simulate a smaller camera, and for TUM max_time_diff (s),
tum_rgb_list, tum_groundtruth. The database is written atomically: a failure
leaves any previous database at `out` intact.

Keywords (the frame source, then the build settings; see
option_defaults()['build']):

{}
Returns the build report as a dict (the CLI's --json): database,
num_frames, num_keyframes, num_skipped, skipped, num_cropped, num_features,
image_bytes, feature_bytes, full_png_bytes, index_bytes, seconds.
)doc";

constexpr const char* kEvaluateDoc =
    R"doc(The paper's experiment (placedb eval): random queries against `db`, judged against ground truth.

Query frames as for build(): images= with truth= (a CSV of true matches,
"query_id,keyframe ids"), or tum= with poses (a keyframe within max_dist
metres and max_angle degrees of the query is correct; or truth=). queries
random queries with ground truth (all=True: every one), chosen by seed;
sequence=True replays them in order, each with the previous answer as
prior_keyframe (for search='cluster'). Every keyword of query() is taken too.

Keywords (the frame source, the ground truth, the evaluation; see
option_defaults()['evaluate']):

{}
Returns the library's evaluation report as a dict: num_queries,
num_correct, num_correct_at_5, num_answerable, recall_at_1, recall_at_5,
verified, precision_recall {{average_precision, recall_at_full_precision,
min_score, at_threshold, curve}}, latency_ms and stage_ms {{mean, p50, p99,
max}}, searches, mean_coverage, num_deadline_reached, database_bytes,
full_frames_png_bytes, reduction_vs_full, truth, and queries (each with its
full QueryResult dict).
)doc";

constexpr const char* kExperimentDoc =
    R"doc(The paper's experiments (placedb experiment): builds and evaluates every
feature x crop x resize x verification setting of the grid into the folder
`out` (resumed when it holds this experiment: finished settings are kept),
writes results.json and, with report=True, report.html.

Query frames and ground truth as for evaluate(); the database's frames are
the query source's, all of them, unless database= (a dict of frame-source
keywords: images or tum, first, last, frame_size, ...) says otherwise, e.g.
database={{"first": 1, "last": 40}}. Returns a dict: num_settings,
num_reused, num_queries, num_database_frames, pictures (paths in the
folder), results (results.json) and report (report.html, or None).

Keywords (the frame source, the ground truth, the experiment's grid and
every build, query and evaluation option it applies to each setting; see
option_defaults()['experiment']):

{}
)doc";

}  // namespace
}  // namespace python
}  // namespace placedb

PYBIND11_MODULE(placedb, m) {
  using namespace placedb;          // NOLINT
  using namespace placedb::python;  // NOLINT

  m.doc() = kModuleDoc;
  m.attr("__version__") = kPlacedbVersion;
  RegisterErrors(m);

  // The library logs through spdlog's default logger: to stderr, as the CLI.
  std::shared_ptr<spdlog::logger> logger = spdlog::get("placedb");
  if (!logger) {
    logger = spdlog::stderr_color_mt("placedb");
    logger->set_pattern("%^[%l]%$ %v");
  }
  spdlog::set_default_logger(logger);

  py::class_<Pose>(m, "Pose",
                   "A rigid camera pose (camera-to-world, as TUM's ground truth): translation in "
                   "metres and a unit quaternion (x, y, z, w).")
      .def(py::init([](const py::object& t, const py::object& q) { return MakePose(t, q); }),
           py::arg("translation"), py::arg("quaternion_xyzw") = py::make_tuple(0.0, 0.0, 0.0, 1.0),
           "Pose(translation=(x, y, z), quaternion_xyzw=(x, y, z, w)); the quaternion is "
           "normalised.")
      .def_property_readonly("translation", &TranslationTuple, "(x, y, z), metres")
      .def_property_readonly("quaternion_xyzw", &QuaternionTuple, "(x, y, z, w), unit length")
      .def(
          "matrix",
          [](const Pose& p) {
            py::array_t<double> out({4, 4});
            auto a = out.mutable_unchecked<2>();
            const Eigen::Matrix3d r = p.rotation.toRotationMatrix();
            for (int i = 0; i < 4; ++i) {
              for (int j = 0; j < 4; ++j) {
                a(i, j) = i < 3 ? (j < 3 ? r(i, j) : p.translation[i]) : (j < 3 ? 0.0 : 1.0);
              }
            }
            return out;
          },
          "The 4x4 homogeneous camera-to-world matrix (float64).")
      .def(
          "to_dict",
          [](const Pose& p) {
            py::dict d;
            d["translation"] = py::list(TranslationTuple(p));
            d["quaternion_xyzw"] = py::list(QuaternionTuple(p));
            return d;
          },
          "{'translation': [x, y, z], 'quaternion_xyzw': [x, y, z, w]}, as in the library's "
          "JSON.")
      .def("__eq__",
           [](const Pose& a, const Pose& b) {
             return a.translation == b.translation && a.rotation.coeffs() == b.rotation.coeffs();
           })
      .def("__repr__", &PoseRepr);

  py::class_<StageTimes>(m, "StageTimes", "Milliseconds spent in each stage of one query.")
      .def_readonly("extract_ms", &StageTimes::extract_ms,
                    "query feature extraction (0 when features were given)")
      .def_readonly("retrieve_ms", &StageTimes::retrieve_ms)
      .def_readonly("match_ms", &StageTimes::match_ms)
      .def_readonly("verify_ms", &StageTimes::verify_ms)
      .def_readonly("total_ms", &StageTimes::total_ms)
      .def("__repr__", [](const StageTimes& t) {
        return fmt::format(
            "StageTimes(extract_ms={:.3f}, retrieve_ms={:.3f}, match_ms={:.3f}, verify_ms={:.3f}, "
            "total_ms={:.3f})",
            t.extract_ms, t.retrieve_ms, t.match_ms, t.verify_ms, t.total_ms);
      });

  py::class_<RankedKeyframe>(m, "RankedKeyframe", "One keyframe of a query's answer.")
      .def_readonly("keyframe_id", &RankedKeyframe::keyframe_id)
      .def_readonly("score", &RankedKeyframe::score,
                    "what the ranking uses: num_inliers when verified, else num_matches")
      .def_readonly("num_matches", &RankedKeyframe::num_matches,
                    "matches that passed the match stage")
      .def_readonly("num_inliers", &RankedKeyframe::num_inliers,
                    "geometric inliers; -1 when not verified")
      .def_property_readonly("verified", &RankedKeyframe::verified)
      .def_property_readonly(
          "pose", [](const RankedKeyframe& k) { return OptionalPose(k.pose); },
          "the keyframe's pose (map coordinates), a Pose, or None when unknown")
      .def_readonly("timestamp", &RankedKeyframe::timestamp,
                    "of the keyframe's source frame, seconds; -1 when unknown")
      .def_property_readonly(
          "source", [](const RankedKeyframe& k) { return FsString(k.source); },
          "the keyframe's source image (a str as os.fsdecode gives)")
      .def_property_readonly(
          "stored_image", [](const RankedKeyframe& k) { return FsString(k.stored_image); },
          "its stored PNG (database directory joined); '' when none")
      .def_readonly("whole_image", &RankedKeyframe::whole_image,
                    "cosine similarity of the whole-image descriptors, in [-1, 1], when the "
                    "channel ran (whole_image_weight or whole_image_candidates > 0); None otherwise")
      .def_readonly("whole_image_z", &RankedKeyframe::whole_image_z,
                    "whole_image standardised over the database's keyframes for this query "
                    "(deviations above their mean); the score adds whole_image_weight x max(0, "
                    "whole_image_z - whole_image_floor). None without the channel")
      .def(
          "to_dict", [](const RankedKeyframe& k) { return FromJsonText(RankedKeyframeToJson(k)); },
          "The library's JSON of this entry, as a dict.")
      .def("__eq__", [](const RankedKeyframe& a, const RankedKeyframe& b) { return a == b; })
      .def("__repr__", &RankedRepr);

  py::class_<QueryResult>(m, "QueryResult",
                          "The answer of a query: a decision (matched, best) and the ranked "
                          "keyframes, with counts and stage times.")
      .def_readonly("matched", &QueryResult::matched,
                    "True when ranked[0] is the answer; False: 'no match / new place'")
      .def_property_readonly(
          "best",
          [](const QueryResult& r) -> py::object {
            if (const RankedKeyframe* b = r.best()) return py::cast(*b);
            return py::none();
          },
          "the answer, a RankedKeyframe, or None for 'no match'")
      .def_readonly("ranked", &QueryResult::ranked,
                    "RankedKeyframes, best first, at most top_k: verified candidates by inliers, "
                    "else by matches")
      .def_readonly("num_query_features", &QueryResult::num_query_features)
      .def_readonly("num_keyframes", &QueryResult::num_keyframes, "in the database searched")
      .def_readonly("num_examined", &QueryResult::num_examined,
                    "keyframes the match stage compared")
      .def_readonly("num_verified", &QueryResult::num_verified, "keyframes the verify stage ran on")
      .def_readonly("coverage", &QueryResult::coverage, "num_examined / num_keyframes, in [0, 1]")
      .def_readonly("deadline_reached", &QueryResult::deadline_reached,
                    "the deadline stopped the match or verify stage early")
      .def_readonly("search", &QueryResult::search,
                    "how candidates were found: 'exhaustive', 'bow', 'cluster', "
                    "'cluster+fallback' or 'cluster+global'")
      .def_readonly("cluster", &QueryResult::cluster, "cluster search: the prior's cluster, -1")
      .def_readonly("times", &QueryResult::times, "StageTimes, milliseconds")
      .def_readonly("decided_by", &QueryResult::decided_by,
                    "'frame' (this frame's own query) or 'sequence' (a SequenceMatcher's path: its "
                    "end is ranked[0] and `matched` is the path's decision)")
      .def_property_readonly(
          "sequence",
          [](const QueryResult& r) -> py::object {
            if (!r.sequence) return py::none();
            return FromJsonText(QueryResultToJson(r))["sequence"];
          },
          "after SequenceMatcher.feed: a dict (keyframe_id: the best path's end, score: its "
          "mean evidence per frame, frames, velocity, frame_keyframe_id, frame_score, "
          "frame_matched: the frame's own answer); None otherwise")
      .def("decision_score", &QueryResult::decision_score,
           "the score the decision was made on: the path's when the sequence answered, else "
           "ranked[0]'s")
      .def(
          "to_dict", [](const QueryResult& r) { return FromJsonText(QueryResultToJson(r)); },
          "The library's JSON of the result (what `placedb query --json` writes, without the "
          "query and database paths), as a dict.")
      .def(
          "to_json",
          [](const QueryResult& r, std::optional<int> indent) {
            return QueryResultToJson(r, indent ? *indent : -1);
          },
          py::arg("indent") = py::none(), "The library's JSON of the result, as a str.")
      .def("__repr__", &ResultRepr);

  py::class_<KeyframeInfo>(m, "Keyframe", "A keyframe of a database (a copy of its record).")
      .def_property_readonly(
          "id", [](const KeyframeInfo& k) { return k.keyframe.id; }, "the source frame's id, >= 1")
      .def_property_readonly(
          "timestamp", [](const KeyframeInfo& k) { return k.keyframe.timestamp; },
          "seconds; -1 when unknown")
      .def_property_readonly(
          "pose", [](const KeyframeInfo& k) { return OptionalPose(k.keyframe.pose); },
          "a Pose, or None when unknown")
      .def_property_readonly(
          "source", [](const KeyframeInfo& k) { return FsString(k.keyframe.source); },
          "path of the source image (a str as os.fsdecode gives: os.fsencode gives its bytes)")
      .def_property_readonly(
          "stored_image", [](const KeyframeInfo& k) { return FsString(k.stored_image); },
          "path of the stored PNG (database directory joined); '' when none")
      .def_property_readonly(
          "image_file", [](const KeyframeInfo& k) { return FsString(k.keyframe.image_file); },
          "the stored PNG relative to the database directory; '' when none")
      .def_property_readonly(
          "crop",
          [](const KeyframeInfo& k) {
            const cv::Rect& c = k.keyframe.crop;
            return py::make_tuple(c.x, c.y, c.width, c.height);
          },
          "(x, y, width, height): the kept region, in the original image")
      .def_property_readonly(
          "crop_channel", [](const KeyframeInfo& k) { return k.keyframe.crop_channel; },
          "winning chromaticity channel, -1: the whole image")
      .def_property_readonly(
          "original_size",
          [](const KeyframeInfo& k) {
            return py::make_tuple(k.keyframe.original_size.width, k.keyframe.original_size.height);
          },
          "(width, height) of the source image; (0, 0) when unknown")
      .def_property_readonly(
          "stored_size",
          [](const KeyframeInfo& k) {
            return py::make_tuple(k.keyframe.stored_size.width, k.keyframe.stored_size.height);
          },
          "(width, height) of the stored (cropped, resized) image")
      .def_property_readonly(
          "scale", [](const KeyframeInfo& k) { return k.keyframe.scale; },
          "stored = (original - crop origin) * scale")
      .def_property_readonly(
          "source_hash", [](const KeyframeInfo& k) { return k.keyframe.source_hash; },
          "XXH3-64 of the source image file's bytes when the keyframe was made; 0 when not "
          "recorded")
      .def_readonly("num_features", &KeyframeInfo::num_features)
      .def("__repr__", [](const KeyframeInfo& k) {
        return fmt::format("Keyframe(id={}, source={}, stored_image={}, pose={})", k.keyframe.id,
                           py::repr(FsString(k.keyframe.source)).cast<std::string>(),
                           py::repr(FsString(k.stored_image)).cast<std::string>(),
                           k.keyframe.pose ? PoseRepr(*k.keyframe.pose) : "None");
      });

  OpenOptions open_defaults;
  const std::string open_doc =
      "Opens the database directory `dir` (PlaceDatabase::Open). Keyword options (OpenOptions; "
      "see option_defaults()['open']):\n\n" +
      DescribeKwargs({Target(&open_defaults)}) +
      "\nA missing database: placedb.NotFoundError (a FileNotFoundError); a damaged one: "
      "placedb.CorruptDatabaseError; bad options: placedb.InvalidArgumentError (a ValueError).";
  QueryOptions query_defaults;
  const std::string query_doc =
      fmt::format(fmt::runtime(kQueryDoc), DescribeKwargs({Target(&query_defaults)}));

  py::class_<PlaceDatabase>(m, "PlaceDatabase",
                            "An open keyframe database with the feature extractor its queries "
                            "need (the library's session API). Queries are thread-safe.")
      .def(py::init(&OpenDatabase), py::arg("dir"), open_doc.c_str())
      .def_static("open", &OpenDatabase, py::arg("dir"), "The same as PlaceDatabase(dir, ...).")
      .def_property_readonly("size", &PlaceDatabase::size, "number of keyframes opened")
      .def("__len__", &PlaceDatabase::size)
      .def_property_readonly(
          "feature_type",
          [](const PlaceDatabase& db) { return FeatureTypeName(db.feature_type()); },
          "'orb' or 'surf'")
      .def_property_readonly("descriptor_width", &DescriptorColumns,
                             "columns of a descriptor row: 32 (ORB, uint8), 64 or 128 (SURF, "
                             "float32)")
      .def_property_readonly("whole_image_dims", &PlaceDatabase::whole_image_dims,
                             "values per keyframe of the whole-image channel (width x height), "
                             "0 when the database has none")
      .def_property_readonly(
          "directory", [](const PlaceDatabase& db) { return FsString(db.directory()); },
          "the folder opened, as given (a str as os.fsdecode gives)")
      .def_property_readonly("reads_features", &PlaceDatabase::reads_features,
                             "whether queries read the keyframes' features from the file "
                             "(read_features, read_features_above_mb) rather than mapping them")
      .def_property_readonly(
          "manifest", [](const PlaceDatabase& db) { return FromJsonText(db.manifest_json()); },
          "the manifest (every build setting, counts, sizes, creation info), a dict")
      .def_property_readonly(
          "keyframe_ids", [](const PlaceDatabase& db) { return db.keyframe_ids(); },
          "ids of the keyframes opened, in file order")
      .def_property_readonly(
          "ids",
          [](const PlaceDatabase& db) {
            const py::object info = FromJsonText(db.info_json());
            return py::object(info["ids"]);
          },
          "the ids as `placedb info` shows them, a dict: count, first, last, next_free (the id "
          "a new frame gets: after the largest the database ever held), removed (keyframes "
          "removed since removed_since; None when not recorded: a database of an earlier "
          "placedb, not saved since)")
      .def(
          "verify",
          [](const PlaceDatabase& db) {
            PlaceDatabase::VerifyReport r;
            {
              py::gil_scoped_release release;
              r = db.Verify();
            }
            py::dict out;
            out["keyframes"] = r.keyframes;
            out["keyframes_bytes"] = r.keyframes_bytes;
            out["format_version"] = r.format_version;
            return out;
          },
          "Checks every byte of the database now (what `placedb verify` does; opening checks "
          "the keyframe table, and a keyframe's features are otherwise checked when a query "
          "first reads them). Returns {keyframes, keyframes_bytes, format_version}; raises "
          "CorruptDatabaseError at the first damage.")
      .def("keyframe", &GetKeyframe, py::arg("id"),
           "The keyframe with this id, a Keyframe; KeyError when there is none.")
      .def("__contains__",
           [](const PlaceDatabase& db, int32_t id) { return db.FindKeyframe(id).has_value(); })
      .def(
          "keyframe_features",
          [](const PlaceDatabase& db, int32_t id) {
            RequireKeyframe(db, id);
            return FromFeatures(db.KeyframeFeatures(id), DescriptorColumns(db));
          },
          py::arg("id"),
          "The stored features of keyframe `id` as (keypoints Nx7 float32, descriptors NxD), in "
          "the stored image's coordinates (SURF rows grouped by Laplacian sign).")
      .def("extract", &Extract, py::arg("image"),
           "The query features of an image, as query() computes them: (keypoints Nx7 float32 "
           "[x, y, size, angle, response, octave, class_id], descriptors NxD uint8 (ORB) or "
           "float32 (SURF)). query_features(*db.extract(image)) gives the answer of "
           "query(image, whole_image_weight=0, whole_image_candidates=0) (features carry no "
           "whole-image row).")
      .def("query", &QueryImage, py::arg("image"), query_doc.c_str())
      .def("query_features", &QueryFeatures, py::arg("keypoints"), py::arg("descriptors"),
           "The same as query() for features computed elsewhere (extract(), another process).\n\n"
           "keypoints: Nx7 float32 (x, y, size, angle, response, octave, class_id) or Nx2 "
           "(x, y), in the query image's pixels; descriptors: NxD uint8 (ORB, D = 32) or "
           "float32 (SURF, D = 64 or 128). They are validated against the database (type, "
           "width, row count, finite positions): ValueError. Keyword options as for query().")
      .def("explain", &ExplainImage, py::arg("image"), py::arg("keyframe_id"),
           "Why keyframe `keyframe_id` matched `image` (or did not): the match and verify "
           "stages on that keyframe alone, as a query counts them. A dict: keyframe_id, "
           "num_matches, verified, num_inliers (-1 unverified), query_points (Nx2 float32, the "
           "query's pixels), keyframe_points (Nx2, the keyframe's original image), distances "
           "(N), inliers (N bool). Keyword options as for query(); KeyError-like ValueError "
           "for an unknown id.")
      .def("draw_match", &DrawMatch, py::arg("image"), py::arg("keyframe_id"),
           py::arg("caption") = "",
           "The query beside keyframe `keyframe_id` with the matches joined by lines (verified "
           "green, rejected amber), as `placedb query --draw` draws it: an HxWx3 BGR uint8 "
           "array. Keyword options as for query().")
      .def("__repr__", [](const PlaceDatabase& db) {
        return fmt::format("<placedb.PlaceDatabase '{}': {} {} keyframes>", db.directory(),
                           db.size(), FeatureTypeName(db.feature_type()));
      });

  FrameSourceOptions source_defaults;
  BuildOptions build_defaults;
  build_defaults.progress = false;
  const std::string build_doc = fmt::format(
      fmt::runtime(kBuildDoc), DescribeKwargs({Target(&source_defaults), Target(&build_defaults)}));
  m.def("build", &Build, py::arg("out"), build_doc.c_str());

  GroundTruthOptions truth_defaults;
  EvalOptions eval_defaults;
  eval_defaults.progress = false;
  const std::string evaluate_doc = fmt::format(
      fmt::runtime(kEvaluateDoc),
      DescribeKwargs({Target(&source_defaults), Target(&truth_defaults), Target(&eval_defaults)}));
  m.def("evaluate", &EvaluateDatabase, py::arg("db"), evaluate_doc.c_str());

  ExperimentOptions experiment_defaults;
  experiment_defaults.progress = false;
  const std::string experiment_doc =
      fmt::format(fmt::runtime(kExperimentDoc),
                  DescribeKwargs({Target(&source_defaults), Target(&truth_defaults),
                                  Target(&experiment_defaults)}));
  m.def("experiment", &RunExperimentInto, py::arg("out"), py::kw_only(),
        py::arg("database") = py::none(), py::arg("report") = true, experiment_doc.c_str());

  m.def("read_image", &ReadImage, py::arg("path"), py::kw_only(),
        py::arg("max_image_pixels") = kDefaultMaxImagePixels,
        "Reads an image file as an HxWx3 uint8 BGR array (decoded by OpenCV, as build and "
        "evaluate read frames), after its header is checked against max_image_pixels (width x "
        "height, [1, 2^30]); ValueError when it cannot be read or is larger.");
  m.def(
      "query_option_defaults",
      []() {
        QueryOptions o;
        return OptionDefaults({Target(&o)});
      },
      "The query options (keywords of query(), query_features(), evaluate()) and their "
      "defaults, a dict.");
  m.def(
      "build_setting_defaults",
      []() {
        BuildOptions o;
        o.progress = false;
        return OptionDefaults({Target(&o)});
      },
      "The build settings (keywords of build()) and their defaults, a dict.");
  SequenceOptions sequence_defaults;
  const std::string sequence_doc = fmt::format(
      "SequenceMatcher(db, **options): sequence-consistent recognition over a stream of "
      "frames (query/sequence.h). Query each frame with db.query() and feed() the result in "
      "the order the frames were taken, or call query(image) which does both; the answer is "
      "the keyframe at the end of the best path through the keyframe order over the last "
      "frames (QueryResult.decided_by, QueryResult.sequence). reset() after a jump (a new "
      "run, a relocalisation). Keywords:\n{}",
      DescribeKwargs({Target(&sequence_defaults)}));
  py::class_<SequenceSession>(m, "SequenceMatcher", sequence_doc.c_str())
      .def(py::init([](const PlaceDatabase& db, const py::kwargs& kwargs) {
             SequenceOptions o;
             ApplyKwargs(kwargs, {Target(&o)}, "SequenceMatcher");
             CheckOptions(o);
             return std::make_unique<SequenceSession>(db, o);
           }),
           py::arg("db"), py::keep_alive<1, 2>(), sequence_doc.c_str())
      .def(
          "feed",
          [](SequenceSession& s, const QueryResult& frame) { return s.matcher.Feed(frame); },
          py::arg("result"),
          "Adds a frame's QueryResult (from db.query) as the newest frame; returns it with the "
          "sequence's decision.")
      .def(
          "query",
          [](SequenceSession& s, const py::object& image, const py::kwargs& kwargs) {
            const QueryOptions options = QueryOptionsFrom(kwargs, "query");
            const ImageInput in = ToImage(image);
            QueryResult frame;
            std::vector<float> similarities;
            {
              py::gil_scoped_release release;
              frame = s.db.Query(in.mat, options,
                                 s.matcher.options().whole_image_weight > 0 ? &similarities
                                                                            : nullptr);
            }
            return s.matcher.Feed(std::move(frame), similarities);
          },
          py::arg("image"), "db.query(image, **query_options), then feed() with the frame's whole-image similarity to every keyframe (the whole map is searched when the database has a whole-image channel and sequence_whole_image_weight > 0): the sequence's answer.")
      .def(
          "reset", [](SequenceSession& s) { s.matcher.Reset(); }, "Forgets every frame.")
      .def(
          "set_keyframes", [](SequenceSession& s) { s.matcher.SetKeyframes(s.db.keyframes()); },
          "Reads the database's keyframes again (after add or remove) and resets.")
      .def_property_readonly("frames_held",
                             [](const SequenceSession& s) { return s.matcher.frames_held(); });
  m.def(
      "option_defaults",
      []() {
        py::dict all;
        OpenOptions open;
        QueryOptions query;
        FrameSourceOptions source;
        BuildOptions build;
        build.progress = false;
        GroundTruthOptions truth;
        EvalOptions eval;
        eval.progress = false;
        all["open"] = OptionDefaults({Target(&open)});
        all["query"] = OptionDefaults({Target(&query)});
        all["build"] = OptionDefaults({Target(&source), Target(&build)});
        all["evaluate"] = OptionDefaults({Target(&source), Target(&truth), Target(&eval)});
        ExperimentOptions experiment;
        experiment.progress = false;
        all["experiment"] = OptionDefaults({Target(&source), Target(&truth), Target(&experiment)});
        SequenceOptions sequence;
        all["sequence"] = OptionDefaults({Target(&sequence)});
        return all;
      },
      "Every keyword of PlaceDatabase() ('open'), query() ('query'), build() ('build'), "
      "evaluate() ('evaluate', with the query options too), experiment() ('experiment') "
      "and SequenceMatcher() ('sequence'), "
      "with its default: a dict of dicts. "
      "They come from the library's option tables, as the command line's flags do.");
  m.def("set_log_level", &SetLogLevel, py::arg("level"),
        "The library's log level: 'trace', 'debug', 'info' (default), 'warn', 'error', "
        "'critical' or 'off'. Logs go to the process's stderr.");
}
