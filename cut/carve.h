#pragma once
// Internal to cut/: removal mode (carving). Deletes every tet that the cut pieces touch
// (exact separating-axis test on current positions), tags the faces it exposes kTagCut and
// deletes vertices left without tets. Loses the removed volume; kept to compare against.
#include <functional>
#include <span>
#include <vector>

#include "cut/cut_piece.h"
#include "mesh/tet_mesh.h"

namespace incise::cut_detail {

struct CarveResult {
  std::size_t removed = 0;
  std::size_t faces_exposed = 0;
  double area = 0;                 // rest area of the exposed faces
  std::vector<TetId> neighbours;   // live tets next to the removed ones
};

CarveResult carve(TetMesh& mesh, std::span<const Piece> pieces, std::span<const TetId> seeds,
                  const std::function<std::vector<TetId>()>& fallback, const std::function<Vec3(VertexId)>& positions);

// True when the (positively or negatively oriented) tet and the triangle share a point
// (separating axis theorem over face normals and edge-edge cross products).
bool tet_intersects_triangle(const std::array<Vec3, 4>& tet, const CutTriangle& tri);

}  // namespace incise::cut_detail
