#pragma once
// How an FEM model treats the volumetric part of the strain; chosen per simulation (scene key
// "formulation"). Standard linear tets lock as Poisson's ratio approaches 0.5: each tet carries
// its own volume constraint, and a mesh has nearly as many tets as unknowns.
//   Standard       one constant strain per tet (the classic linear tetrahedron).
//   NodalAveraged  deviatoric strain per tet, volumetric strain averaged at the vertices
//                  (Bonet & Burton 1998, "average nodal pressure"): one constraint per vertex,
//                  no volumetric locking, still one SPD displacement system (CG, warm start,
//                  budgets and local updates unchanged). Needs Poisson's ratio < 0.5.
//   EdgeSmoothed   volumetric strain averaged at the vertices as NodalAveraged, and the
//                  deviatoric strain smoothed over the tets around each edge (edge-based
//                  smoothed FEM, Liu, Nguyen-Thoi & Lam 2009; with the nodal volumetric part the
//                  "selective ES/NS-FEM-T4"): removes most of linear tets' bending stiffness
//                  as well (docs/solver.md#bending-as-well-edge-smoothed-tets-formulationedgesmoothed).
//                  Same SPD system.
//   Mixed          displacement and a vertex pressure as unknowns (stabilized P1-P1), a
//                  symmetric saddle-point system; valid at Poisson's ratio 0.5.
//   MixedEdgeSmoothed  Mixed with the displacement block's strain smoothed over edge domains
//                  as EdgeSmoothed does: the mixed formulation's validity at 0.5 and the
//                  edge-smoothed element's bending.
//   Quadratic      10-node tets (P2 displacement: corners and mid-edge nodes, sim/fem/p2_mesh.h),
//                  one SPD displacement system, assembled (sim/fem/quadratic_solver.h). For
//                  references and offline accuracy, not the real-time path (docs/solver.md#quadratic-tets).
//   MixedQuadratic Taylor-Hood: P2 displacement and a P1 (vertex) pressure, inf-sup stable
//                  without stabilization; valid at Poisson's ratio 0.5.
#include <optional>
#include <string_view>

namespace incise {

enum class Formulation { Standard, NodalAveraged, EdgeSmoothed, Mixed, MixedEdgeSmoothed, Quadratic, MixedQuadratic };

inline std::string_view formulation_name(Formulation f) {
  switch (f) {
    case Formulation::Standard: return "standard";
    case Formulation::NodalAveraged: return "nodal-averaged";
    case Formulation::EdgeSmoothed: return "edge-smoothed";
    case Formulation::Mixed: return "mixed";
    case Formulation::MixedEdgeSmoothed: return "mixed-edge-smoothed";
    case Formulation::Quadratic: return "quadratic";
    case Formulation::MixedQuadratic: return "mixed-quadratic";
  }
  return "standard";
}

inline std::optional<Formulation> parse_formulation(std::string_view s) {
  if (s == "standard") return Formulation::Standard;
  if (s == "nodal-averaged") return Formulation::NodalAveraged;
  if (s == "edge-smoothed") return Formulation::EdgeSmoothed;
  if (s == "mixed") return Formulation::Mixed;
  if (s == "mixed-edge-smoothed") return Formulation::MixedEdgeSmoothed;
  if (s == "quadratic") return Formulation::Quadratic;
  if (s == "mixed-quadratic") return Formulation::MixedQuadratic;
  return std::nullopt;
}

// For messages: the names parse_formulation() accepts.
inline constexpr std::string_view kFormulationNames =
    "\"standard\", \"nodal-averaged\", \"edge-smoothed\", \"mixed\", \"mixed-edge-smoothed\", \"quadratic\" or "
    "\"mixed-quadratic\"";

// Pressure as an unknown on linear tets (the saddle-point solver of sim/fem/mixed_solver.h).
inline bool is_mixed(Formulation f) { return f == Formulation::Mixed || f == Formulation::MixedEdgeSmoothed; }
// 10-node tets (sim/fem/quadratic_solver.h).
inline bool is_quadratic(Formulation f) { return f == Formulation::Quadratic || f == Formulation::MixedQuadratic; }
// Poisson's ratio 0.5 allowed: a pressure unknown carries the volumetric part.
inline bool allows_incompressible(Formulation f) { return is_mixed(f) || f == Formulation::MixedQuadratic; }
// The strain of the displacement block smoothed over edge domains.
inline bool smooths_edges(Formulation f) {
  return f == Formulation::EdgeSmoothed || f == Formulation::MixedEdgeSmoothed;
}

}  // namespace incise
