#include "sim/material.h"

#include <cstdio>

#include <cmath>

#include "mesh/errors.h"

namespace incise {

void check_material(const Material& m, const std::string& what, bool incompressible_ok) {
  if (!(m.young > 0) || !std::isfinite(m.young))
    throw InvalidArgument(what + ".young: expected a finite Young's modulus > 0");
  if (!(m.density > 0) || !std::isfinite(m.density))
    throw InvalidArgument(what + ".density: expected a finite density > 0");
  if (!(m.viscosity >= 0) || !std::isfinite(m.viscosity))
    throw InvalidArgument(what + ".viscosity: expected a finite time constant >= 0 [s]");
  if (!(m.stiffening >= 0) || !(m.stiffening <= 100))
    throw InvalidArgument(what + ".stiffening: expected a value in [0, 100]");
  if (!(m.poisson >= 0) || !std::isfinite(m.poisson))
    throw InvalidArgument(what + ".poisson: expected a Poisson's ratio in [0, 0.5)");
  if (m.poisson > 0.5 || (m.poisson == 0.5 && !incompressible_ok))
    throw InvalidArgument(what + ".poisson: " + std::to_string(m.poisson) +
                          " is >= 0.5; displacement-only elasticity is singular at 0.5 (incompressible) and "
                          "unstable above; use at most 0.4999, or the mixed formulation for 0.5");
  // Below 0.5 but so close that lambda / mu = 2 nu / (1 - 2 nu) passes 1e8: the stiffness is
  // singular to double precision: CG cannot converge on it (docs/solver.md, formulations).
  if (m.poisson < 0.5 && !incompressible_ok && 1 - 2 * m.poisson < 2e-8) {
    char nu[32];
    std::snprintf(nu, sizeof nu, "%.17g", m.poisson);
    throw InvalidArgument(what + ".poisson: " + nu +
                          " is within 1e-8 of 0.5: displacement-only stiffness is singular to double precision "
                          "there; use at most 0.4999, or the mixed formulation up to 0.5");
  }
}

void MaterialTable::set_default(const Material& m) {
  check_material(m, "materials.*", true);
  default_ = m;
  has_default_ = true;
}

void MaterialTable::set(int label, const Material& m) {
  check_material(m, "materials." + std::to_string(label), true);
  by_label_[label] = m;
}

const Material& MaterialTable::get(int label) const {
  auto it = by_label_.find(label);
  if (it != by_label_.end()) return it->second;
  if (!has_default_)
    throw InvalidArgument("materials: no material for region label " + std::to_string(label) +
                          " (give one for every label of the mesh, or a default for the rest)");
  return default_;
}

}  // namespace incise
