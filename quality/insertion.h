#pragma once
// Vertex insertion where flips and smoothing are stuck (e.g. a tet spanning a thin part with
// all four vertices on the surface): an interior edge of the tet is split and the new vertex
// placed where its star is best (star_ascent.h). Evaluated completely before acting, so it
// is applied only when the new star is better() than the edge's star. The new vertex is
// recorded as inserted on the edge, then moved (parents: a tet of the old edge star).
#include <optional>
#include <vector>

#include "mesh/tet_mesh.h"
#include "quality/improve_scope.h"

namespace incise {

struct InsertionOutcome {
  VertexId vertex;
  std::vector<TetId> removed, added;
};

std::optional<InsertionOutcome> improve_by_insertion(TetMesh& mesh, TetId t, const ImproveScope& scope,
                                                     int max_ring = 7, int iterations = 16);

}  // namespace incise
