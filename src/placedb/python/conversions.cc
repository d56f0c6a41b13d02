#include "placedb/python/conversions.h"

#include <climits>
#include <cmath>
#include <cstring>
#include <vector>

#include "placedb/util/check.h"

namespace placedb {
namespace python {
namespace {

std::string TypeName(py::handle h) { return Py_TYPE(h.ptr())->tp_name; }

// `h` as a NumPy array (no copy when it is one); TypeError when it cannot be.
py::array AsArray(py::handle h, const std::string& what) {
  if (h.is_none()) throw py::type_error(what + " must be a NumPy array, got None");
  py::array a = py::array::ensure(h);
  if (!a) throw py::type_error(what + " must be a NumPy array, got " + TypeName(h));
  return a;
}

bool IsDtype(const py::array& a, char kind, py::ssize_t itemsize) {
  return a.dtype().kind() == kind && a.itemsize() == itemsize;
}

int CheckedDim(const py::array& a, int axis, const std::string& what) {
  if (a.shape(axis) > INT_MAX) {
    PLACEDB_THROW_INVALID(what + " is too large: shape " + ShapeString(a));
  }
  return static_cast<int>(a.shape(axis));
}

// A keypoint's octave or class_id: a whole number that fits an int.
int WholeNumber(float v, size_t row, const char* what) {
  if (!std::isfinite(v) || v != std::floor(v) || v < -2147483648.0f || v >= 2147483648.0f) {
    PLACEDB_THROW_INVALID("keypoint " + std::to_string(row) + ": " + what +
                          " must be a whole number (got " + std::to_string(v) + ")");
  }
  return static_cast<int>(v);
}

std::vector<double> Numbers(py::handle seq, size_t n, const std::string& what) {
  if (!PySequence_Check(seq.ptr()) || PyUnicode_Check(seq.ptr()) ||
      static_cast<size_t>(PySequence_Size(seq.ptr())) != n) {
    if (PyErr_Occurred()) PyErr_Clear();
    throw py::type_error(what + " must be a sequence of " + std::to_string(n) + " numbers, got " +
                         TypeName(seq));
  }
  std::vector<double> v;
  for (size_t i = 0; i < n; ++i) {
    const py::object item = py::reinterpret_steal<py::object>(
        PySequence_GetItem(seq.ptr(), static_cast<py::ssize_t>(i)));
    if (!item) throw py::error_already_set();
    v.push_back(ToDouble(item, what));
    if (!std::isfinite(v.back())) PLACEDB_THROW_INVALID(what + " must be finite");
  }
  return v;
}

}  // namespace

std::string DtypeName(const py::array& a) { return py::str(a.dtype()).cast<std::string>(); }

std::string ShapeString(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) {
    if (i > 0) s += ", ";
    s += std::to_string(a.shape(i));
  }
  if (a.ndim() == 1) s += ",";
  return s + ")";
}

ImageInput ToImage(py::handle image) {
  const py::array a = AsArray(image, "image");
  if (!IsDtype(a, 'u', 1)) {
    PLACEDB_THROW_INVALID("image must be a uint8 array (8-bit gray, BGR or BGRA), got dtype " +
                          DtypeName(a));
  }
  int channels = 0;
  if (a.ndim() == 2) {
    channels = 1;
  } else if (a.ndim() == 3 && (a.shape(2) == 1 || a.shape(2) == 3 || a.shape(2) == 4)) {
    channels = static_cast<int>(a.shape(2));
  } else {
    PLACEDB_THROW_INVALID("image must be HxW (gray), HxWx3 (BGR) or HxWx4 (BGRA), got shape " +
                          ShapeString(a));
  }
  const int rows = CheckedDim(a, 0, "image");
  const int cols = CheckedDim(a, 1, "image");
  ImageInput in;
  in.array = py::array_t<uint8_t, py::array::c_style>::ensure(a);
  if (!in.array) throw py::error_already_set();
  in.mat = cv::Mat(rows, cols, CV_8UC(channels), const_cast<void*>(in.array.data()));
  return in;
}

FeatureInput ToFeatures(py::handle keypoints, py::handle descriptors) {
  FeatureInput in;
  const py::array d = AsArray(descriptors, "descriptors");
  if (d.ndim() != 2) {
    PLACEDB_THROW_INVALID("descriptors must be an NxD array (one row per keypoint), got shape " +
                          ShapeString(d));
  }
  int depth = CV_8U;
  if (IsDtype(d, 'u', 1)) {
    in.set.type = FeatureType::kOrb;
    in.descriptors = py::array_t<uint8_t, py::array::c_style>::ensure(d);
  } else if (IsDtype(d, 'f', 4)) {
    in.set.type = FeatureType::kSurf;
    depth = CV_32F;
    in.descriptors = py::array_t<float, py::array::c_style>::ensure(d);
  } else if (IsDtype(d, 'f', 8)) {
    in.set.type = FeatureType::kSurf;
    depth = CV_32F;
    in.descriptors = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(d);
  } else {
    PLACEDB_THROW_INVALID("descriptors must be uint8 (ORB) or float32 (SURF), got dtype " +
                          DtypeName(d));
  }
  if (!in.descriptors) throw py::error_already_set();
  const int rows = CheckedDim(d, 0, "descriptors");
  const int cols = CheckedDim(d, 1, "descriptors");
  in.set.descriptors =
      cv::Mat(rows, cols, CV_MAKETYPE(depth, 1), const_cast<void*>(in.descriptors.data()));

  const py::array k = AsArray(keypoints, "keypoints");
  if (k.ndim() != 2 || (k.shape(1) != 2 && k.shape(1) != 7)) {
    PLACEDB_THROW_INVALID(
        "keypoints must be an Nx2 (x, y) or Nx7 (x, y, size, angle, response, octave, "
        "class_id) array, got shape " +
        ShapeString(k));
  }
  const char kind = k.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') {
    PLACEDB_THROW_INVALID("keypoints must be a real-valued array (float32 preferred), got dtype " +
                          DtypeName(k));
  }
  const auto kf = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(k);
  if (!kf) throw py::error_already_set();
  const size_t n = static_cast<size_t>(kf.shape(0));
  const size_t width = static_cast<size_t>(kf.shape(1));
  const float* p = kf.data();
  in.set.keypoints.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const float* row = p + i * width;
    cv::KeyPoint& kp = in.set.keypoints[i];
    kp.pt = cv::Point2f(row[0], row[1]);
    if (width == 7) {
      kp.size = row[2];
      kp.angle = row[3];
      kp.response = row[4];
      kp.octave = WholeNumber(row[5], i, "octave");
      kp.class_id = WholeNumber(row[6], i, "class_id");
    }
  }
  return in;
}

py::tuple FromFeatures(const FeatureSet& features, int empty_cols) {
  const py::ssize_t n = static_cast<py::ssize_t>(features.size());
  py::array_t<float> keypoints({n, static_cast<py::ssize_t>(7)});
  auto k = keypoints.mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < n; ++i) {
    const cv::KeyPoint& kp = features.keypoints[static_cast<size_t>(i)];
    k(i, 0) = kp.pt.x;
    k(i, 1) = kp.pt.y;
    k(i, 2) = kp.size;
    k(i, 3) = kp.angle;
    k(i, 4) = kp.response;
    k(i, 5) = static_cast<float>(kp.octave);
    k(i, 6) = static_cast<float>(kp.class_id);
  }
  const cv::Mat& d = features.descriptors;
  const bool orb = d.empty() ? features.type == FeatureType::kOrb : d.depth() == CV_8U;
  const py::dtype dtype = orb ? py::dtype::of<uint8_t>() : py::dtype::of<float>();
  const int rows = d.empty() ? 0 : d.rows;
  const int cols = d.empty() ? empty_cols : d.cols;
  py::array descriptors(dtype, {static_cast<py::ssize_t>(rows), static_cast<py::ssize_t>(cols)});
  const size_t row_bytes = static_cast<size_t>(cols) * (orb ? 1 : sizeof(float));
  for (int r = 0; r < rows; ++r) {
    std::memcpy(descriptors.mutable_data(r), d.ptr(r), row_bytes);
  }
  return py::make_tuple(keypoints, descriptors);
}

py::array FromImage(const cv::Mat& image) {
  std::vector<py::ssize_t> shape = {image.rows, image.cols};
  if (image.channels() > 1) shape.push_back(image.channels());
  py::array_t<uint8_t> out(shape);
  const size_t row_bytes = static_cast<size_t>(image.cols) * image.elemSize();
  for (int r = 0; r < image.rows; ++r) std::memcpy(out.mutable_data(r), image.ptr(r), row_bytes);
  return std::move(out);
}

py::object FromJson(const nlohmann::json& j) {
  switch (j.type()) {
    case nlohmann::json::value_t::null:
    case nlohmann::json::value_t::discarded:
      return py::none();
    case nlohmann::json::value_t::boolean:
      return py::bool_(j.get<bool>());
    case nlohmann::json::value_t::number_integer:
      return py::int_(j.get<int64_t>());
    case nlohmann::json::value_t::number_unsigned:
      return py::int_(j.get<uint64_t>());
    case nlohmann::json::value_t::number_float:
      return py::float_(j.get<double>());
    case nlohmann::json::value_t::string:
      return py::str(j.get_ref<const std::string&>());
    case nlohmann::json::value_t::binary: {
      const auto& b = j.get_binary();
      return py::bytes(reinterpret_cast<const char*>(b.data()), b.size());
    }
    case nlohmann::json::value_t::array: {
      py::list list;
      for (const auto& e : j) list.append(FromJson(e));
      return std::move(list);
    }
    case nlohmann::json::value_t::object: {
      py::dict dict;
      for (auto it = j.begin(); it != j.end(); ++it) dict[py::str(it.key())] = FromJson(it.value());
      return std::move(dict);
    }
  }
  return py::none();
}

py::tuple TranslationTuple(const Pose& pose) {
  const auto& t = pose.translation;
  return py::make_tuple(t.x(), t.y(), t.z());
}

py::tuple QuaternionTuple(const Pose& pose) {
  const auto& q = pose.rotation;
  return py::make_tuple(q.x(), q.y(), q.z(), q.w());
}

Pose MakePose(py::handle translation, py::handle quaternion_xyzw) {
  const std::vector<double> t = Numbers(translation, 3, "translation");
  const std::vector<double> q = Numbers(quaternion_xyzw, 4, "quaternion_xyzw");
  Pose pose;
  pose.translation = Eigen::Vector3d(t[0], t[1], t[2]);
  const Eigen::Quaterniond rotation(q[3], q[0], q[1], q[2]);  // (w, x, y, z)
  const double norm = rotation.norm();
  if (!(norm > 1e-12) || !std::isfinite(norm)) {
    PLACEDB_THROW_INVALID("quaternion_xyzw must not be zero");
  }
  pose.rotation = rotation.normalized();
  return pose;
}

Pose ToPose(py::handle pose, const std::string& what) {
  if (py::isinstance<Pose>(pose)) return pose.cast<Pose>();
  if (PySequence_Check(pose.ptr()) && !PyUnicode_Check(pose.ptr()) &&
      PySequence_Size(pose.ptr()) == 2) {
    const py::sequence s = py::reinterpret_borrow<py::sequence>(pose);
    return MakePose(s[0], s[1]);
  }
  if (PyErr_Occurred()) PyErr_Clear();
  throw py::type_error(what +
                       " must be a placedb.Pose or a pair (translation (x, y, z), "
                       "quaternion (x, y, z, w)), got " +
                       TypeName(pose));
}

int ToInt(py::handle value, const std::string& name) {
  if (PyBool_Check(value.ptr()) || !PyIndex_Check(value.ptr())) {
    throw py::type_error(name + " must be an integer, got " + TypeName(value));
  }
  const py::object index = py::reinterpret_steal<py::object>(PyNumber_Index(value.ptr()));
  if (!index) throw py::error_already_set();
  int overflow = 0;
  const long long v = PyLong_AsLongLongAndOverflow(index.ptr(), &overflow);
  if (overflow != 0 || v < INT_MIN || v > INT_MAX) {
    PLACEDB_THROW_INVALID(name + " does not fit a 32-bit integer (got " +
                          py::str(index).cast<std::string>() + ")");
  }
  return static_cast<int>(v);
}

uint64_t ToUint64(py::handle value, const std::string& name) {
  if (PyBool_Check(value.ptr()) || !PyIndex_Check(value.ptr())) {
    throw py::type_error(name + " must be an integer, got " + TypeName(value));
  }
  const py::object index = py::reinterpret_steal<py::object>(PyNumber_Index(value.ptr()));
  if (!index) throw py::error_already_set();
  const unsigned long long v = PyLong_AsUnsignedLongLong(index.ptr());
  if (PyErr_Occurred()) {
    PyErr_Clear();
    PLACEDB_THROW_INVALID(name + " must be in [0, 2^64) (got " +
                          py::str(index).cast<std::string>() + ")");
  }
  return static_cast<uint64_t>(v);
}

double ToDouble(py::handle value, const std::string& name) {
  if (PyBool_Check(value.ptr()) || PyUnicode_Check(value.ptr()) || PyBytes_Check(value.ptr()) ||
      !PyNumber_Check(value.ptr())) {
    throw py::type_error(name + " must be a number, got " + TypeName(value));
  }
  const double v = PyFloat_AsDouble(value.ptr());
  if (v == -1.0 && PyErr_Occurred()) {
    PyErr_Clear();
    throw py::type_error(name + " must be a real number, got " + TypeName(value));
  }
  return v;
}

bool ToBool(py::handle value, const std::string& name) {
  if (PyBool_Check(value.ptr())) return value.ptr() == Py_True;
  if (TypeName(value) == std::string("numpy.bool_")) return PyObject_IsTrue(value.ptr()) == 1;
  throw py::type_error(name + " must be True or False, got " + TypeName(value));
}

std::string ToString(py::handle value, const std::string& name) {
  if (!PyUnicode_Check(value.ptr())) {
    throw py::type_error(name + " must be a str, got " + TypeName(value));
  }
  return value.cast<std::string>();
}

std::string ToPath(py::handle value, const std::string& name) {
  const py::object path = py::reinterpret_steal<py::object>(PyOS_FSPath(value.ptr()));
  if (!path) {
    PyErr_Clear();
    throw py::type_error(name + " must be a path (str or os.PathLike), got " + TypeName(value));
  }
  if (PyBytes_Check(path.ptr())) return path.cast<py::bytes>();
  return path.cast<std::string>();
}

}  // namespace python
}  // namespace placedb
