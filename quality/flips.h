#pragma once
// Topological improvement around one tet: the best of the 2-3 flips across its faces and the
// edge removals (3-2, 4-4, n-to-2(n-2) with the optimal ring triangulation) of its edges,
// and the removal of its boundary edges between coplanar faces (boundary_flips.h).
// Only operations inside one label, inside the scope, and that better() the replaced tets
// are applied; the mesh's checks have the last word.
#include <vector>

#include "mesh/tet_mesh.h"
#include "quality/improve_scope.h"

namespace incise {

struct FlipOutcome {
  enum Kind { None, Flip23, Flip32, Flip44, EdgeRemoval, BoundaryFlip } kind = None;
  std::vector<TetId> removed;  // ids of the replaced tets (may be reused by `added`)
  std::vector<TetId> added;
};

// Applies the best improving flip involving tet t (max_ring: largest edge ring tried).
FlipOutcome improve_by_flip(TetMesh& mesh, TetId t, const ImproveScope& scope, int max_ring = 7);

}  // namespace incise
