#pragma once
// Internal to cut/: removal mode (carving). Deletes every tet that the cut pieces touch
// (exact separating-axis test on current positions), tags the faces it exposes kTagCut and
// deletes vertices left without tets; pinched edges and vertices are repaired (see repair_manifold). Loses the removed volume; kept to compare against.
#include <functional>
#include <span>
#include <unordered_set>
#include <vector>

#include "cut/cut_piece.h"
#include "mesh/id_set.h"
#include "mesh/tet_mesh.h"

namespace incise::cut_detail {

struct CarveResult {
  std::size_t removed = 0;
  std::size_t faces_exposed = 0;
  double area = 0;                 // rest area of the exposed faces
  std::vector<TetId> neighbours;   // live tets next to the removed ones
  std::vector<std::pair<TetId, int>> exposed;  // candidate faces (some removed again later)
};

CarveResult carve(TetMesh& mesh, std::span<const Piece> pieces, std::span<const TetId> seeds,
                  const std::function<std::vector<TetId>()>& fallback, const std::function<Vec3(VertexId)>& positions);

// Keeps the boundary a closed 2-manifold around the `touched` vertices after tets were
// removed: tets of extra fans around a non-manifold edge are removed too (through `remove`,
// which must append the removed tet's vertices to `touched`), then vertices whose star falls
// into several parts are duplicated. Local: only the stars of touched vertices are visited.
void repair_manifold(TetMesh& mesh, std::vector<VertexId>& touched, IdSet& doomed,
                     const std::function<void(TetId)>& remove);

// True when the (positively or negatively oriented) tet and the triangle share a point
// (separating axis theorem over face normals and edge-edge cross products).
bool tet_intersects_triangle(const std::array<Vec3, 4>& tet, const CutTriangle& tri);

}  // namespace incise::cut_detail
