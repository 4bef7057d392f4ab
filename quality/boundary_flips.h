#pragma once
// Boundary edge removal: a boundary edge (a,b) whose two boundary faces (a,b,c_0) and
// (a,b,c_m) are coplanar and carry the same tag is replaced by the diagonal c_0-c_m of their
// quad, and the tets around it by the 2(m-1) tets on the best triangulation of the open ring
// c_0..c_m (edge_removal.h). m = 2 is the boundary 2-2 flip. The surface, its tags and the
// volume stay exactly; only one label; the new boundary faces take the old faces' tag.
// Built from remove_tet/add_tet, so it lands in the pending TopologyChange like any edit.
#include <array>
#include <optional>
#include <vector>

#include "mesh/tet_mesh.h"
#include "quality/improve_scope.h"

namespace incise {

struct BoundaryEdgeRemoval {
  VertexId a, b;
  std::vector<std::array<int, 3>> triangles;  // into the open ring c_0..c_m
  AngleQuality after;                         // worst of the new tets
  std::vector<TetId> removed;
};

// The best improving boundary edge removal of (a,b), if there is one (max_ring: most tets
// around the edge tried).
std::optional<BoundaryEdgeRemoval> plan_boundary_edge_removal(const TetMesh& mesh, VertexId a, VertexId b,
                                                              const ImproveScope& scope, int max_ring);
// Applies a plan made on the current mesh; returns the new tets.
std::vector<TetId> remove_boundary_edge(TetMesh& mesh, const BoundaryEdgeRemoval& plan);

}  // namespace incise
