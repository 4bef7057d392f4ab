#pragma once
// Internal to cut/: opening the cut. Each vertex of a cut face keeps one connected component of
// its tet star (components joined across faces that are not cut) and gets one duplicate per
// further component, so the two sides separate along the whole cut surface while a vertex on
// the cut front (one component) stays shared. An edge of the cut surface joining two such
// vertices across it (a chord) is split first, so the rim is the only place the sides stay
// joined. Opened faces are tagged kTagCut.
#include <span>
#include <utility>
#include <vector>

#include "cut/cut_step.h"
#include "mesh/tet_mesh.h"

namespace incise::cut_detail {

struct SeparationResult {
  std::size_t vertices_duplicated = 0;  // new vertices made
  std::size_t faces_opened = 0;         // cut faces that became boundary (pairs)
  std::size_t faces_dropped = 0;        // left closed: they would have pinched the boundary
  double area = 0;                      // rest area of the opened faces (one side)
  std::vector<TetId> opened_tets;       // one tet on each side of every opened face
  std::vector<std::pair<VertexId, VertexId>> duplicates;  // (vertex, its new copy)
  // Chords of the cut surface split at their midpoint (an edge between two rim vertices with
  // cut faces on both sides, see separate.cpp): the new vertex lies on the cut surface.
  struct Split {
    VertexId mid, a, b;
  };
  std::vector<Split> splits;
  std::vector<CutFacePair> shut;  // input faces still closed, with their tets after the splits
};

// The caller records the current positions of the new vertices (splits: the midpoint of a
// and b; duplicates: the vertex's).
// split_chords false: chords stay whole and their faces shut (a progressive step, whose rim
// next to the waiting tets moves on: the next steps open those faces, and splitting chords
// there grew the mesh on through-cuts in many steps; docs/cut.md#the-defaults).
SeparationResult separate(TetMesh& mesh, std::span<const CutFacePair> faces, bool split_chords = true);

}  // namespace incise::cut_detail
