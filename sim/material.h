#pragma once
// Materials per region label: Young's modulus, Poisson's ratio, density. Shared by every
// simulation backend so a scene describes tissue once.
#include <string>
#include <unordered_map>

namespace incise {

struct Material {
  double young = 1e6;     // Young's modulus E [Pa], > 0
  double poisson = 0.3;   // Poisson's ratio nu, in [0, 0.5]: 0.5 (incompressible) only for the mixed formulation
  double density = 1000;  // [kg/m^3], > 0
  // Springs only (sim/springs/spring_model.h, docs/solver.md#spring-options); 0: SpringOptions' value.
  double viscosity = 0;   // Kelvin-Voigt time constant [s], >= 0
  double stiffening = 0;  // exponential strain-stiffening exponent, in [0, 100]

  // Lame parameters.
  double lambda() const { return young * poisson / ((1 + poisson) * (1 - 2 * poisson)); }
  double mu() const { return young / (2 * (1 + poisson)); }
};

// Throws InvalidArgument naming `what` (e.g. "materials.2") and the bad field. Poisson's ratio
// 0.5 passes only with `incompressible_ok`: a table may hold it (for the mixed formulation,
// which keeps pressure as an unknown), displacement-only models refuse it (lambda is infinite).
void check_material(const Material& m, const std::string& what, bool incompressible_ok = false);

class MaterialTable {
public:
  MaterialTable() = default;
  explicit MaterialTable(const Material& fallback) { set_default(fallback); }
  void set_default(const Material& m);                      // used for labels not set explicitly
  // No default: get() of a label not set throws InvalidArgument (a table meant to name every
  // label, e.g. Python's {label: Material}: a label the mesh has and the table lacks is an error,
  // not silently Material()). set_default() gives it one again.
  void clear_default() { has_default_ = false; }
  bool has_default() const { return has_default_; }
  void set(int label, const Material& m);
  const Material& get(int label) const;                     // O(1)
  const Material& fallback() const { return default_; }
  const std::unordered_map<int, Material>& by_label() const { return by_label_; }

private:
  Material default_;
  bool has_default_ = true;
  std::unordered_map<int, Material> by_label_;
};

}  // namespace incise
