#pragma once
// The rules on user-given improvement options, shared by `incise improve` and the Python
// module (one rule, one wording). `Names` spells an option the way the caller's user wrote
// it: CliNames gives "--target-dihedral", PythonNames "target_dihedral".
#include <string>

#include "mesh/errors.h"
#include "mesh/io/input_checks.h"
#include "quality/improve.h"

namespace incise {

struct CliNames {
  std::string operator()(const std::string& snake) const {
    std::string s = "--" + snake;
    for (char& c : s)
      if (c == '_') c = '-';
    return s;
  }
};
struct PythonNames {
  std::string operator()(const std::string& snake) const { return snake; }
};

// A finite number in [lo, hi], else InvalidArgument("WHAT: NAME: reason").
template <class Names>
void check_finite_range(const std::string& what, const std::string& snake, double v, double lo, double hi,
                        const Names& name) {
  const std::string e = finite_range_error(v, lo, hi);
  if (!e.empty()) throw InvalidArgument(what + ": " + name(snake) + ": " + e);
}

// The options both front ends expose, checked before any work.
template <class Names>
void check_improve_options(const ImproveOptions& o, const Names& name) {
  if (!(o.target_dihedral_deg > 0 && o.target_dihedral_deg < 70.5 && o.target_max_dihedral_deg > 70.6 &&
        o.target_max_dihedral_deg < 180))
    throw InvalidArgument("improve: targets must satisfy 0 < " + name("target_dihedral") + " < 70.5 < " +
                          name("target_max_dihedral") + " < 180");
  if (!(o.radius_ratio_floor > 0 && o.radius_ratio_floor <= 1))
    throw InvalidArgument("improve: " + name("radius_ratio_floor") + " must be in (0, 1]");
  if (!(o.max_growth >= 1) || !std::isfinite(o.max_growth))
    throw InvalidArgument("improve: " + name("max_growth") + " must be at least 1");
  check_finite_range("improve", "feature_angle", o.feature_angle_deg, 0, 180, name);
  check_finite_range("improve", "time_limit", o.time_limit_s, 0, 1e6, name);
  check_finite_range("improve", "volume_tolerance", o.volume_tolerance, 0, 1, name);
  check_finite_range("improve", "feature_line_angle", o.feature_line_angle_deg, 0, 180, name);
  check_finite_range("improve", "surface_flip_deviation", o.surface_flip_deviation, 0, 1, name);
  check_finite_range("improve", "max_slides", o.max_curved_slides, 0, 1000, name);
}

}  // namespace incise
