#pragma once
// Option checks shared by the subcommands: one rule, one wording. CLI11's Range lets NaN
// through (every comparison with NaN is false) and prints its bounds with std::to_string (a
// 300-digit number for DBL_MAX); these do neither. Failures reach main() as CLI11 validation
// errors, printed as one line naming the option.
#include <cmath>
#include <sstream>
#include <string>

#include <CLI/CLI.hpp>

#include "mesh/io/input_checks.h"

namespace incise::cli {

using incise::number_text;

// A finite number in [lo, hi]; `note` (e.g. "0: no limit") is shown in --help.
inline CLI::Validator finite_range(double lo, double hi, const std::string& note = "") {
  const std::string range = "[" + number_text(lo) + ", " + number_text(hi) + "]";
  return CLI::Validator(
      [lo, hi](std::string& s) -> std::string {
        double v = 0;
        if (!CLI::detail::lexical_cast(s, v)) return "'" + s + "' is not a number";
        return finite_range_error(v, lo, hi, s);
      },
      "in " + range + (note.empty() ? "" : "; " + note));
}

// A time limit in seconds or milliseconds: finite, >= 0, at most `max` (a larger one would
// overflow the clock's duration); 0 means no limit.
inline CLI::Validator time_limit_range(double max) { return finite_range(0, max, "0: no limit"); }

}  // namespace incise::cli
