#include "placedb/python/conversions.h"

#include <climits>
#include <cmath>
#include <cstring>
#include <vector>

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
    throw InvalidArgument(what + " is too large: shape " + ShapeString(a));
  }
  return static_cast<int>(a.shape(axis));
}

// A keypoint's octave or class_id: a whole number that fits an int.
int WholeNumber(float v, size_t row, const char* what) {
  if (!std::isfinite(v) || v != std::floor(v) || v < -2147483648.0f || v >= 2147483648.0f) {
    throw InvalidArgument("keypoint " + std::to_string(row) + ": " + what +
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
    if (PyBool_Check(item.ptr()) || PyUnicode_Check(item.ptr()) || !PyNumber_Check(item.ptr())) {
      throw py::type_error(what + " must hold numbers, got " + TypeName(item));
    }
    const double d = PyFloat_AsDouble(item.ptr());
    if (d == -1.0 && PyErr_Occurred()) throw py::error_already_set();
    v.push_back(d);
    if (!std::isfinite(v.back())) throw InvalidArgument(what + " must be finite");
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
    throw InvalidArgument("image must be a uint8 array (8-bit gray, BGR or BGRA), got dtype " +
                          DtypeName(a));
  }
  int channels = 0;
  if (a.ndim() == 2) {
    channels = 1;
  } else if (a.ndim() == 3 && (a.shape(2) == 1 || a.shape(2) == 3 || a.shape(2) == 4)) {
    channels = static_cast<int>(a.shape(2));
  } else {
    throw InvalidArgument("image must be HxW (gray), HxWx3 (BGR) or HxWx4 (BGRA), got shape " +
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
    throw InvalidArgument("descriptors must be an NxD array (one row per keypoint), got shape " +
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
    throw InvalidArgument("descriptors must be uint8 (ORB) or float32 (SURF), got dtype " +
                          DtypeName(d));
  }
  if (!in.descriptors) throw py::error_already_set();
  const int rows = CheckedDim(d, 0, "descriptors");
  const int cols = CheckedDim(d, 1, "descriptors");
  in.set.descriptors =
      cv::Mat(rows, cols, CV_MAKETYPE(depth, 1), const_cast<void*>(in.descriptors.data()));

  const py::array k = AsArray(keypoints, "keypoints");
  if (k.ndim() != 2 || (k.shape(1) != 2 && k.shape(1) != 7)) {
    throw InvalidArgument(
        "keypoints must be an Nx2 (x, y) or Nx7 (x, y, size, angle, response, octave, "
        "class_id) array, got shape " +
        ShapeString(k));
  }
  const char kind = k.dtype().kind();
  if (kind != 'f' && kind != 'i' && kind != 'u') {
    throw InvalidArgument("keypoints must be a real-valued array (float32 preferred), got dtype " +
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

py::str FsString(const std::string& path) {
  PyObject* text =
      PyUnicode_DecodeFSDefaultAndSize(path.data(), static_cast<Py_ssize_t>(path.size()));
  if (text == nullptr) throw py::error_already_set();
  return py::reinterpret_steal<py::str>(text);
}

py::list FsStrings(const std::vector<std::string>& paths) {
  py::list out;
  for (const std::string& p : paths) out.append(FsString(p));
  return out;
}

py::object FromJsonText(const std::string& json) {
  return py::module_::import("json").attr("loads")(py::str(json));
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
    throw InvalidArgument("quaternion_xyzw must not be zero");
  }
  pose.rotation = rotation.normalized();
  return pose;
}

}  // namespace python
}  // namespace placedb
