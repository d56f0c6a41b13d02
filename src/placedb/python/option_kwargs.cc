#include "placedb/python/option_kwargs.h"

#include <fmt/format.h>

#include <climits>
#include <cstdint>

namespace placedb {
namespace python {
namespace {

std::string TypeName(py::handle h) { return Py_TYPE(h.ptr())->tp_name; }

[[noreturn]] void WrongType(const OptionField& f, const char* wanted, py::handle value) {
  throw py::type_error(fmt::format("{} must be {}, got {}", f.name, wanted, TypeName(value)));
}

// Python ints and NumPy's integer scalars (anything with __index__), not
// bools; numbers add floats and NumPy's float scalars.
bool IsBool(py::handle v) {
  return PyBool_Check(v.ptr()) || std::string(Py_TYPE(v.ptr())->tp_name) == "numpy.bool_";
}
bool IsInteger(py::handle v) {
  return !IsBool(v) && !PyFloat_Check(v.ptr()) && PyIndex_Check(v.ptr());
}
bool IsNumber(py::handle v) {
  return IsInteger(v) || (!IsBool(v) && !PyUnicode_Check(v.ptr()) && !PyBytes_Check(v.ptr()) &&
                          PyFloat_Check(v.ptr())) ||
         std::string(Py_TYPE(v.ptr())->tp_name).rfind("numpy.float", 0) == 0;
}
bool IsText(py::handle v) {
  return PyUnicode_Check(v.ptr()) || PyObject_HasAttrString(v.ptr(), "__fspath__");
}
bool IsSequence(py::handle v) {
  return (PyList_Check(v.ptr()) || PyTuple_Check(v.ptr()));
}

OptionValue Integer(py::handle value, const OptionField& f) {
  const py::object v = py::reinterpret_steal<py::object>(PyNumber_Index(value.ptr()));
  if (!v) throw py::error_already_set();
  int overflow = 0;
  const long long i = PyLong_AsLongLongAndOverflow(v.ptr(), &overflow);
  if (overflow == 0) return static_cast<int64_t>(i);
  if (overflow > 0) {
    const unsigned long long u = PyLong_AsUnsignedLongLong(v.ptr());
    if (!PyErr_Occurred()) return static_cast<uint64_t>(u);
    PyErr_Clear();
  }
  throw py::value_error(fmt::format("{} is out of range (got {})", f.name,
                                    py::str(v).cast<std::string>()));
}

std::string Text(py::handle v) {
  if (PyUnicode_Check(v.ptr())) return v.cast<std::string>();
  const py::object path = py::module_::import("os").attr("fspath")(v);
  if (!PyUnicode_Check(path.ptr())) {
    throw py::type_error("paths must be str (bytes paths are not supported)");
  }
  return path.cast<std::string>();
}

// A list/tuple of numbers, or of str, or (for a pose) a pair (translation,
// quaternion) or a placedb.Pose.
OptionValue Sequence(py::handle v, const OptionField& f) {
  const py::sequence s = py::reinterpret_borrow<py::sequence>(v);
  bool all_text = true, all_numbers = true;
  for (const py::handle item : s) {
    all_text = all_text && IsText(item);
    all_numbers = all_numbers && IsNumber(item);
  }
  if (s.size() == 0 || all_numbers) {
    std::vector<double> numbers;
    for (const py::handle item : s) numbers.push_back(PyFloat_AsDouble(item.ptr()));
    return numbers;
  }
  if (all_text) {
    std::vector<std::string> items;
    for (const py::handle item : s) items.push_back(Text(item));
    return items;
  }
  // A pose as a pair: ((x, y, z), (qx, qy, qz, qw)).
  if (f.kind == OptionKind::kNumbers && s.size() == 2 && IsSequence(s[0]) && IsSequence(s[1])) {
    std::vector<double> numbers;
    for (const py::handle part : {s[0], s[1]}) {
      for (const py::handle item : py::reinterpret_borrow<py::sequence>(part)) {
        if (!IsNumber(item)) WrongType(f, "a list of numbers", item);
        numbers.push_back(item.cast<double>());
      }
    }
    return numbers;
  }
  WrongType(f, "a list of numbers or of names", v);
}

}  // namespace

OptionValue FromPython(py::handle v, const OptionField& f) {
  switch (f.kind) {
    case OptionKind::kBool:
      if (!IsBool(v)) WrongType(f, "True or False", v);
      return PyObject_IsTrue(v.ptr()) == 1;
    case OptionKind::kInt:
    case OptionKind::kUint64:
      if (!IsInteger(v)) WrongType(f, "an integer", v);
      return Integer(v, f);
    case OptionKind::kDouble:
      if (!IsNumber(v)) WrongType(f, "a number", v);
      if (IsInteger(v)) return Integer(v, f);
      return PyFloat_AsDouble(v.ptr());
    case OptionKind::kText:
    case OptionKind::kChoice:
      if (v.is_none()) return std::vector<double>();  // "none", where the option has one
      if (IsText(v)) return Text(v);
      if (IsSequence(v)) return Sequence(v, f);  // (i, n), (w, h)
      WrongType(f, "a str", v);
    case OptionKind::kList:
      if (v.is_none()) return std::vector<std::string>();
      if (IsText(v)) return std::vector<std::string>{Text(v)};
      if (IsSequence(v)) return Sequence(v, f);
      WrongType(f, "a list", v);
    case OptionKind::kNumbers: {
      if (v.is_none()) return std::vector<double>();
      if (py::hasattr(v, "translation") && py::hasattr(v, "quaternion_xyzw")) {
        std::vector<double> numbers;
        for (const char* part : {"translation", "quaternion_xyzw"}) {
          for (const py::handle item : v.attr(part)) numbers.push_back(item.cast<double>());
        }
        return numbers;
      }
      if (IsSequence(v)) return Sequence(v, f);
      WrongType(f, "a list of numbers", v);
    }
  }
  WrongType(f, "a value", v);
}

py::object ToPython(const OptionValue& value, const OptionField& f) {
  struct Visitor {
    const OptionField& f;
    py::object operator()(bool b) const { return py::bool_(b); }
    py::object operator()(int64_t i) const { return py::int_(i); }
    py::object operator()(uint64_t u) const { return py::int_(u); }
    py::object operator()(double d) const { return py::float_(d); }
    py::object operator()(const std::string& s) const {
      // An optional choice or text that is not set reads as None.
      if (s.empty() && (f.kind == OptionKind::kChoice || f.name == "partition")) return py::none();
      return py::str(s);
    }
    py::object operator()(const std::vector<std::string>& l) const {
      py::list out;
      for (const std::string& s : l) out.append(s);
      return std::move(out);
    }
    py::object operator()(const std::vector<double>& l) const {
      if (l.empty()) return py::none();
      py::tuple out(l.size());
      for (size_t i = 0; i < l.size(); ++i) out[i] = l[i];
      return std::move(out);
    }
  };
  return std::visit(Visitor{f}, value);
}

void ApplyKwargs(const py::kwargs& kwargs, std::initializer_list<KwargsTarget> targets,
                 const char* function) {
  for (const auto& item : kwargs) {
    const std::string name = py::str(item.first).cast<std::string>();
    bool done = false;
    for (const KwargsTarget& t : targets) {
      const OptionTableBase::Entry* e = t.table->Find(name);
      if (e == nullptr || (e->field.surfaces & kPython) == 0) continue;
      e->set(t.options, FromPython(item.second, e->field));
      done = true;
      break;
    }
    if (!done) {
      std::string known;
      for (const KwargsTarget& t : targets) {
        for (const auto& e : t.table->entries()) {
          if (e.field.surfaces & kPython) known += (known.empty() ? "" : ", ") + e.field.name;
        }
      }
      throw py::type_error(fmt::format("{}() got an unexpected keyword argument '{}' (its "
                                       "options are: {})",
                                       function, name, known));
    }
  }
}

py::dict OptionDefaults(std::initializer_list<KwargsTarget> targets) {
  py::dict d;
  for (const KwargsTarget& t : targets) {
    for (const auto& e : t.table->entries()) {
      if (e.field.surfaces & kPython) d[e.field.name.c_str()] = ToPython(e.get(t.options), e.field);
    }
  }
  return d;
}

std::string DescribeKwargs(std::initializer_list<KwargsTarget> targets) {
  std::string out;
  for (const KwargsTarget& t : targets) {
    for (const auto& e : t.table->entries()) {
      const OptionField& f = e.field;
      if ((f.surfaces & kPython) == 0) continue;
      out += "    " + f.name + " = " +
             py::repr(ToPython(e.get(t.options), f)).cast<std::string>() + "\n";
      std::string help = FormatOptionNames(f.help, OptionNames::kKeywords);
      if (f.kind != OptionKind::kBool && f.kind != OptionKind::kText && f.range != "any")
        help += " (" + FormatOptionNames(f.range, OptionNames::kKeywords) + ")";
      // Wrapped at 79 columns under an 8-space indent.
      std::string line;
      size_t begin = 0;
      while (begin < help.size()) {
        size_t end = help.find(' ', begin);
        if (end == std::string::npos) end = help.size();
        const std::string word = help.substr(begin, end - begin);
        if (!line.empty() && line.size() + 1 + word.size() > 71) {
          out += "        " + line + "\n";
          line.clear();
        }
        line += (line.empty() ? "" : " ") + word;
        begin = end + 1;
      }
      if (!line.empty()) out += "        " + line + "\n";
    }
  }
  return out;
}

}  // namespace python
}  // namespace placedb
