#pragma once
// Boundary edge removal: a boundary edge (a,b) whose two boundary faces (a,b,c_0) and
// (a,b,c_m) are coplanar and carry the same tag is replaced by the diagonal c_0-c_m of their
// quad, and the tets around it by the 2(m-1) tets on the best triangulation of the open ring
// c_0..c_m (edge_removal.h). m = 2 is the boundary 2-2 flip. The surface, its tags and the
// volume stay exactly; only one label; the new boundary faces take the old faces' tag.
// With a SurfaceReshape the two faces need not be coplanar, and m may be 1 (the tet holding
// both faces is peeled off: a flat boundary sliver whose far edge c_0-c_m is interior) (one tag still): the surface then
// moves by the tet (a, b, c_0, c_m), the edge (a, b) must stay within `deviation` times the
// shorter of (a, b) and (c_0, c_m) of the new edge, and the label's volume change is spent from
// the allowance (refused past it).
// Built from remove_tet/add_tet, so it lands in the pending TopologyChange like any edit.
#include <array>
#include <optional>
#include <vector>

#include "mesh/tet_mesh.h"
#include "quality/improve_scope.h"
#include "quality/volume_allowance.h"

namespace incise {

struct BoundaryEdgeRemoval {
  VertexId a, b;
  std::vector<std::array<int, 3>> triangles;  // into the open ring c_0..c_m
  AngleQuality after;                         // worst of the new tets
  std::vector<TetId> removed;
  double volume_change = 0;  // the label's volume after minus before (0 when coplanar)
  int label = 0;             // of the star's tets
};

struct SurfaceReshape {
  double deviation = 0.1;               // old edge to new edge, relative to the shorter
  const VolumeAllowance* volume = nullptr;  // what the label may still change (nullptr: no limit)
};

// The best improving boundary edge removal of (a,b), if there is one (max_ring: most tets
// around the edge tried).
std::optional<BoundaryEdgeRemoval> plan_boundary_edge_removal(const TetMesh& mesh, VertexId a, VertexId b,
                                                              const ImproveScope& scope, int max_ring,
                                                              const SurfaceReshape* reshape = nullptr);
// Applies a plan made on the current mesh; returns the new tets.
std::vector<TetId> remove_boundary_edge(TetMesh& mesh, const BoundaryEdgeRemoval& plan);

}  // namespace incise
