#pragma once
// Optimization-based smoothing (Freitag and Ollivier-Gooch): move one vertex to raise the
// worst angle_quality() of its incident tets by nonsmooth steepest ascent (the direction is
// the smallest vector in the convex hull of the active tets' gradients; the step is halved
// until the worst value rises). Interior vertices move freely; a boundary vertex moves only
// within its plane when all its boundary faces are coplanar, carry one tag and form one
// disc, so the surface (and each cut plane) stays where it was. Vertices whose tets carry
// several labels (interfaces) stay. The move goes through TetMesh::move_vertex, recorded as
// a point of the mesh before the move.
#include <cstdint>
#include <unordered_set>

#include "mesh/tet_mesh.h"
#include "quality/improve_scope.h"

namespace incise {

struct SmoothOptions {
  bool move_surface = true;  // boundary (non-cut) vertices may slide in flat neighbourhoods
  bool move_cut = true;      // vertices on cut-tagged faces may slide in their plane
  int iterations = 8;        // ascent steps
  const std::unordered_set<std::uint32_t>* frozen = nullptr;  // vertex ids that never move
};

// Returns true when v moved (its tets strictly better by better()).
bool smooth_vertex(TetMesh& mesh, VertexId v, const ImproveScope& scope, const SmoothOptions& opt);

}  // namespace incise
