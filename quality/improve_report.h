#pragma once
// The improvement report for people (before -> after lines) and programs (JSON, schema
// incise.improve/1), shared by `incise improve`, `incise prepare` and the Python module.
#include <string>

#include <nlohmann/json.hpp>

#include "quality/improve.h"

namespace incise {

std::string format_improve_report(const ImproveReport& r);
nlohmann::json improve_report_json(const ImproveReport& r);

}  // namespace incise
