// Conversions between Python objects (NumPy arrays, dicts, tuples) and the
// library's types, for the placedb module. No logic of the library is
// repeated here: arrays become the cv::Mat / FeatureSet the library takes,
// and the library's own JSON becomes Python dicts.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "placedb/placedb.h"

namespace placedb {
namespace python {

namespace py = pybind11;

// A NumPy image viewed as a cv::Mat without a copy. `array` (C-contiguous,
// uint8) owns the pixels: keep the struct alive while `mat` is used.
struct ImageInput {
  py::array array;
  cv::Mat mat;
};
// uint8 HxW (gray), HxWx1, HxWx3 (BGR) or HxWx4 (BGRA); any strides (a
// non-contiguous array is copied). Another dtype or shape: ValueError; not
// array-like: TypeError. An empty array is passed on (the library says so).
ImageInput ToImage(py::handle image);

// Query features from NumPy arrays, as a FeatureSet. The descriptors are
// viewed without a copy (C-contiguous), `array` owns them.
//   keypoints   Nx2 (x, y) or Nx7 (x, y, size, angle, response, octave,
//               class_id), any real dtype (converted to float32); Nx2 gets
//               cv::KeyPoint's defaults (size 0, angle -1, response 0,
//               octave 0, class_id -1).
//   descriptors NxD uint8 (ORB) or float32 (SURF; float64 is converted).
// The type of the set follows the descriptors' dtype; everything else (row
// count, width, finite positions) the library validates against the
// database.
struct FeatureInput {
  py::array descriptors;
  FeatureSet set;
};
FeatureInput ToFeatures(py::handle keypoints, py::handle descriptors);

// The inverse of ToFeatures: (keypoints Nx7 float32, descriptors NxD uint8 or
// float32), copies. `empty_cols` is D when the set is empty.
py::tuple FromFeatures(const FeatureSet& features, int empty_cols);

// A BGR (or gray) 8-bit cv::Mat as a new HxWx3 (HxW) uint8 array.
py::array FromImage(const cv::Mat& image);

// A path (bytes, as the file system holds them) as a Python str the way
// os.fsdecode makes one: the file-system encoding, bytes that are not part
// of it as surrogate escapes (os.fsencode gives the same bytes back). Never
// raises for a field read. Every path the module returns goes through it.
py::str FsString(const std::string& path);
py::list FsStrings(const std::vector<std::string>& paths);

// The library's JSON text as Python (json.loads): null -> None, bool, int,
// float, str, list, dict.
py::object FromJsonText(const std::string& json);

// Pose <-> Python tuples: translation (x, y, z), quaternion (x, y, z, w).
py::tuple TranslationTuple(const Pose& pose);
py::tuple QuaternionTuple(const Pose& pose);
// A pose from a translation (3 numbers) and a quaternion (x, y, z, w; 4
// numbers, normalised). Non-finite values or a zero quaternion: ValueError.
Pose MakePose(py::handle translation, py::handle quaternion_xyzw);
// "float32", "int64", ... of an array-like.
std::string DtypeName(const py::array& a);
// "(480, 640, 3)".
std::string ShapeString(const py::array& a);

}  // namespace python
}  // namespace placedb
