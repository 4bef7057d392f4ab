#pragma once
// Checks of user input shared by the CLI, scene files and the Python module: one rule, one
// wording, wherever the value comes from.
#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise {

// A number as people write it (1e+06, not std::to_string's 1000000.000000 or 300 digits).
inline std::string number_text(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// Why v is not a finite number in [lo, hi] (empty when it is); `text` is v as the user wrote it.
// NaN fails every comparison, so it is caught explicitly.
inline std::string finite_range_error(double v, double lo, double hi, const std::string& text) {
  const std::string range = "[" + number_text(lo) + ", " + number_text(hi) + "]";
  if (!std::isfinite(v)) return "'" + text + "': expected a finite number in " + range;
  if (v < lo || v > hi) return text + " is out of range " + range;
  return {};
}
inline std::string finite_range_error(double v, double lo, double hi) {
  return finite_range_error(v, lo, hi, number_text(v));
}

// The wording for a point with a NaN or infinite coordinate (readers, the mesh builder, the
// Python module): such a mesh could be written but not read back, and its angles are NaN.
inline std::string non_finite_point(std::size_t i) {
  return "non-finite point coordinate (point " + std::to_string(i) + ")";
}

// Why a blade from a to b moved by d sweeps no area (empty when it does): such a cut would
// do nothing, or something odd, and report success.
inline std::string degenerate_sweep(const Vec3& a, const Vec3& b, const Vec3& d) {
  const double scale = std::max({a.norm(), b.norm(), (a + d).norm(), 1e-300});
  // Lengths below a trillionth of the coordinates are lost to rounding: say so when they are
  // not zero (a blade 2e15 long swept by 3 does not look "zero" to its user).
  const auto lost = [&](double length, const char* what) {
    return std::string(what) + " (" + number_text(length) + ") is lost to rounding at the blade's coordinates (up to " +
           number_text(scale) + "): keep the blade near the body";
  };
  if ((b - a).norm() <= 1e-12 * scale)
    return (b - a).norm() == 0 ? "the blade's two ends are the same point" : lost((b - a).norm(), "the blade's length");
  if (d.norm() <= 1e-12 * scale)
    return d.norm() == 0 ? "the sweep is zero: the blade does not move" : lost(d.norm(), "the sweep's length");
  if ((b - a).normalized().cross(d.normalized()).norm() <= 1e-9) return "the sweep is parallel to the blade: it sweeps no area";
  return {};
}

}  // namespace incise
