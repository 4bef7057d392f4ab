#pragma once
// Checks of user input shared by the CLI, scene files and the Python module: one rule, one
// wording, wherever the value comes from.
#include <algorithm>
#include <string>

#include "mesh/tet_mesh.h"

namespace incise {

// Why a blade from a to b moved by d sweeps no area (empty when it does): such a cut would
// do nothing, or something odd, and report success.
inline std::string degenerate_sweep(const Vec3& a, const Vec3& b, const Vec3& d) {
  const double scale = std::max({a.norm(), b.norm(), (a + d).norm(), 1e-300});
  if ((b - a).norm() <= 1e-12 * scale) return "the blade's two ends are the same point";
  if (d.norm() <= 1e-12 * scale) return "the sweep is zero: the blade does not move";
  if ((b - a).normalized().cross(d.normalized()).norm() <= 1e-9) return "the sweep is parallel to the blade: it sweeps no area";
  return {};
}

}  // namespace incise
