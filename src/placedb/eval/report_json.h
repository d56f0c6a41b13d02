// The reports of evaluation and benchmarks as nlohmann JSON, for the
// library's own writers (experiment results, tests); clients take the text
// (EvalReportJson, BenchReportJson). Not part of the public face.
#pragma once

#include <nlohmann/json.hpp>

#include "placedb/eval/bench.h"
#include "placedb/eval/evaluate.h"

namespace placedb {

nlohmann::json EvalReportToJson(const EvalReport& report);
nlohmann::json BenchReportToJson(const BenchReport& report);

}  // namespace placedb
