// Keyword arguments of the placedb module, made from the library's option
// tables (util/option_table.h): every option a table shows to Python
// (kPython) is a keyword of the functions that take its struct, named and
// checked as the table says, so Python, the CLI and a manifest cannot
// disagree. Types: TypeError for a value of the wrong Python type (a str for
// a number, True for an int); the library's InvalidArgument (ValueError) for
// a value out of range.
#pragma once

#include <pybind11/pybind11.h>

#include <initializer_list>
#include <string>
#include <vector>

#include "placedb/placedb.h"

namespace placedb {
namespace python {

namespace py = pybind11;

// One options struct a function takes keywords for.
struct KwargsTarget {
  const OptionTableBase* table;
  void* options;
};
template <typename T>
KwargsTarget Target(T* options) {
  return {&T::Table(), options};
}

// Sets every keyword of `kwargs` on the target whose table has it (a
// keyword no target takes: TypeError listing the known ones; `function`
// names the call in it). The structs' Check() is not run: the caller checks
// them (PLACEDB_CHECK_OPTIONS through the library).
void ApplyKwargs(const py::kwargs& kwargs, std::initializer_list<KwargsTarget> targets,
                 const char* function);

// A Python value for an option, and the option's value as Python.
OptionValue FromPython(py::handle value, const OptionField& field);
py::object ToPython(const OptionValue& value, const OptionField& field);

// name -> the targets' current values (their defaults), and the docstring
// block that lists them with their help and range.
py::dict OptionDefaults(std::initializer_list<KwargsTarget> targets);
std::string DescribeKwargs(std::initializer_list<KwargsTarget> targets);

}  // namespace python
}  // namespace placedb
