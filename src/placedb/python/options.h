// Keyword arguments of the placedb module mapped onto the library's options
// structs. Each option is named after its placedb CLI flag (--top-k ->
// top_k) and sets one field; the structs' own Check() decides what is valid,
// so Python, the CLI and a manifest get the same answer.
#pragma once

#include <pybind11/pybind11.h>

#include <functional>
#include <string>
#include <vector>

#include "placedb/build/builder.h"
#include "placedb/query/query.h"

namespace placedb {
namespace python {

namespace py = pybind11;

template <typename Options>
struct OptionSpec {
  const char* name;  // the keyword
  const char* help;  // one line, with the range
  std::function<void(Options&, py::handle, const std::string&)> set;
  std::function<py::object(const Options&)> get;
};

// Every field of QueryOptions: top_k, min_score, verify, search, deadline_ms,
// prior_keyframe, prior_pose, ratio, ...
const std::vector<OptionSpec<QueryOptions>>& QuerySpecs();
// The build settings: features, crop, resize, index, overwrite, threads, the
// extractor, crop and vocabulary knobs, ...
const std::vector<OptionSpec<BuildOptions>>& BuildSpecs();

// `defaults` with `kwargs` applied, then Check()ed. Unknown keywords and
// values of the wrong type: TypeError; invalid values: ValueError (the
// library's reason). `what` names the struct in messages.
QueryOptions QueryOptionsFrom(const py::kwargs& kwargs, QueryOptions defaults = QueryOptions());
BuildOptions BuildOptionsFrom(const py::kwargs& kwargs, BuildOptions defaults);

// name -> default value, and the docstring block listing the options.
template <typename Options>
py::dict OptionValues(const std::vector<OptionSpec<Options>>& specs, const Options& options) {
  py::dict d;
  for (const auto& s : specs) d[s.name] = s.get(options);
  return d;
}
template <typename Options>
std::string DescribeOptions(const std::vector<OptionSpec<Options>>& specs,
                            const Options& defaults) {
  std::string out;
  for (const auto& s : specs) {
    out += "    ";
    out += s.name;
    out += " = ";
    out += py::repr(s.get(defaults)).template cast<std::string>();
    // The help, wrapped at 79 columns under an 8-space indent.
    std::string line;
    size_t begin = 0;
    const std::string help = s.help;
    while (begin < help.size()) {
      size_t end = help.find(' ', begin);
      if (end == std::string::npos) end = help.size();
      const std::string word = help.substr(begin, end - begin);
      if (!line.empty() && line.size() + 1 + word.size() > 71) {
        out += "\n        " + line;
        line.clear();
      }
      line += (line.empty() ? "" : " ") + word;
      begin = end + 1;
    }
    out += "\n        " + line + "\n";
  }
  return out;
}

}  // namespace python
}  // namespace placedb
