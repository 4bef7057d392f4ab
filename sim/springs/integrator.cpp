#include "sim/springs/integrator.h"

#include "mesh/errors.h"

namespace incise {

Integrator parse_integrator(const std::string& name) {
  if (name == "explicit-euler") return Integrator::ExplicitEuler;
  if (name == "symplectic-euler") return Integrator::SymplecticEuler;
  if (name == "verlet") return Integrator::Verlet;
  if (name == "implicit-euler") return Integrator::ImplicitEuler;
  throw InvalidArgument("integrator: unknown name '" + name +
                        "'; expected explicit-euler, symplectic-euler, verlet or implicit-euler");
}

const char* integrator_name(Integrator integrator) {
  switch (integrator) {
    case Integrator::ExplicitEuler: return "explicit-euler";
    case Integrator::SymplecticEuler: return "symplectic-euler";
    case Integrator::Verlet: return "verlet";
    case Integrator::ImplicitEuler: return "implicit-euler";
  }
  return "unknown";
}

}  // namespace incise
