#pragma once
// Time integrators for the dynamic models, named as scenes spell them.
#include <string>

namespace incise {

enum class Integrator {
  ExplicitEuler,    // x += dt v_n, v += dt a(x_n, v_n): gains energy at any dt without damping
  SymplecticEuler,  // v += dt a(x_n, v_n), x += dt v_{n+1}: bounded energy below the stable step
  Verlet,           // velocity Verlet, one force evaluation per step (acceleration is cached)
  ImplicitEuler,    // linearized backward Euler, one CG solve per step: unconditionally stable
};

// "explicit-euler", "symplectic-euler", "verlet", "implicit-euler"; throws InvalidArgument
// listing the accepted names otherwise.
Integrator parse_integrator(const std::string& name);
const char* integrator_name(Integrator integrator);
inline bool is_explicit(Integrator integrator) { return integrator != Integrator::ImplicitEuler; }

}  // namespace incise
