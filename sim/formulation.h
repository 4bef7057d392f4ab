#pragma once
// How an FEM model treats the volumetric part of the strain; chosen per simulation (scene key
// "formulation"). Standard linear tets lock as Poisson's ratio approaches 0.5: each tet carries
// its own volume constraint, and a mesh has nearly as many tets as unknowns.
//   Standard       one constant strain per tet (the classic linear tetrahedron).
//   NodalAveraged  deviatoric strain per tet, volumetric strain averaged at the vertices
//                  (Bonet & Burton 1998, "average nodal pressure"): one constraint per vertex,
//                  no volumetric locking, still one SPD displacement system (CG, warm start,
//                  budgets and local updates unchanged). Needs Poisson's ratio < 0.5.
//   Mixed          displacement and a vertex pressure as unknowns (stabilized P1-P1), a
//                  symmetric saddle-point system; valid at Poisson's ratio 0.5.
#include <optional>
#include <string_view>

namespace incise {

enum class Formulation { Standard, NodalAveraged, Mixed };

inline std::string_view formulation_name(Formulation f) {
  switch (f) {
    case Formulation::Standard: return "standard";
    case Formulation::NodalAveraged: return "nodal-averaged";
    case Formulation::Mixed: return "mixed";
  }
  return "standard";
}

inline std::optional<Formulation> parse_formulation(std::string_view s) {
  if (s == "standard") return Formulation::Standard;
  if (s == "nodal-averaged") return Formulation::NodalAveraged;
  if (s == "mixed") return Formulation::Mixed;
  return std::nullopt;
}

}  // namespace incise
