#pragma once
// Internal to cut/: snapping by moving (Nienhuys & van der Stappen 2001). A vertex within the
// snap threshold of the cut plane counts as lying on it; left where it is, the cut surface
// bends through it, and a bent cut surface freezes its vertices for the improvement
// (smoothing slides cut vertices only within a flat disc, contraction removes them only
// there), so the slivers around it stay. An interior vertex is moved onto the plane instead,
// when its tets stay valid and no worse than min(their worst, kSnapMoveFloorDeg): the cut
// surface stays planar there. Vertices on the body's surface, on a cut, or on a label
// interface stay (moving them would move the surface or a label's volume).
#include <functional>
#include <optional>
#include <unordered_set>

#include "cut/cut_piece.h"
#include "mesh/id_set.h"
#include "mesh/tet_mesh.h"

namespace incise::cut_detail {

// A move may lower the smallest dihedral angle of the vertex's tets only down to this.
constexpr double kSnapMoveFloorDeg = 10;

// Moves v onto the piece's plane (in the current configuration given by `position`; rest
// follows with the same barycentric weights, recorded by TetMesh::move_vertex) and returns
// its new current position, or nothing when v may not or should not move. `fixed`: vertices
// that never move (CutOptions::frozen).
std::optional<Vec3> move_onto_plane(TetMesh& mesh, VertexId v, const Piece& piece,
                                    const std::function<Vec3(VertexId)>& position,
                                    const IdSet& fixed);

}  // namespace incise::cut_detail
