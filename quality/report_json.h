#pragma once
// The quality report as JSON, schema "incise.quality/1" (docs/quality-report.md): the one
// writer behind `incise quality --json`, `incise prepare`'s report and the Python
// incise.quality(). Non-finite or unavailable numbers are written as null, never as NaN.
#include <nlohmann/json.hpp>

#include "mesh/io/tet_io.h"
#include "quality/report.h"

namespace incise {

inline constexpr const char* kQualitySchema = "incise.quality/1";

nlohmann::json quality_report_json(const QualityReport& report);
// The same for a mesh read from `file`, with "file" and "read" (format, reoriented tets,
// skipped cells): what `incise quality FILE --json` prints.
nlohmann::json quality_report_json(const QualityReport& report, const std::string& file, const ReadReport& read);

}  // namespace incise
