#pragma once
// Topological improvement around one tet: the best of the 2-3 flips and multi-face removals
// (multi_face_removal.h) across its faces, the edge removals (3-2, 4-4, n-to-2(n-2) with the
// optimal ring triangulation) of its edges, and the removal of its boundary edges between
// coplanar faces (boundary_flips.h).
// Only operations inside one label, inside the scope, and that better() the replaced tets
// are applied; the mesh's checks have the last word.
#include <vector>

#include "mesh/tet_mesh.h"
#include "quality/boundary_flips.h"
#include "quality/improve_scope.h"

namespace incise {

struct FlipOutcome {
  enum Kind { None, Flip23, Flip32, Flip44, EdgeRemoval, MultiFaceRemoval, BoundaryFlip } kind = None;
  std::vector<TetId> removed;  // ids of the replaced tets (may be reused by `added`)
  std::vector<TetId> added;
  bool surface_moved = false;  // a boundary flip between faces that are not coplanar
};

struct FlipOptions {
  int max_ring = 7;          // edge removal: largest ring (tets around the edge) tried
  bool multi_face = true;    // multi-face removal (2m -> m+2 tets, m >= 3; m = 1, 2 are the 2-3 and 4-4 flips)
  int max_sandwich = 16;     // multi-face removal: most faces explored from one start face
  // Boundary flips between faces that are not coplanar, within this (nullptr: coplanar only);
  // an applied one spends its volume change from reshape_volume.
  const SurfaceReshape* reshape = nullptr;
  VolumeAllowance* reshape_volume = nullptr;
};

// Applies the best improving flip involving tet t.
FlipOutcome improve_by_flip(TetMesh& mesh, TetId t, const ImproveScope& scope, const FlipOptions& opt = {});

}  // namespace incise
