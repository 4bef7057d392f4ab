#pragma once
// Edge contraction (edge collapse): vertex `remove` is merged into its neighbour `keep`,
// which stays where it is. The tets around the edge disappear; every other tet of `remove`
// is rebuilt on `keep`. It is what fixes a very short edge (a cut passing close to an
// existing vertex leaves one, with slivers around it that flips and smoothing cannot repair).
//
// Check, then act, like TetMesh's flips. check_collapse() is purely local (the stars of the
// two vertices) and refuses, without touching the mesh, when the collapse would
//  - break the topology: the link condition Lk(keep) ∩ Lk(remove) = Lk(edge), with the
//    boundary coned to a virtual vertex (Dey et al.), so the mesh stays a manifold with
//    boundary and no face is shared by three tets;
//  - invert or flatten a tet (signed volume above 1e-12 l^3 for its longest edge l), or
//    change the volume the star of `remove` covers (it is retiled exactly or not at all);
//  - change the boundary: `remove` may be a boundary vertex only when its boundary faces form
//    one flat disc (tolerance 1e-10 of its size) with one tag and `keep` lies on the disc's rim,
//    or two such flat parts meeting along a straight crease through `remove` (two boundary
//    edges in line: a box's edge, the rim where a cut meets the surface) and `keep` lies on
//    that crease; every retiled face keeps its orientation in its plane. Corners, bent creases
//    and curved parts never lose a vertex, and a crease vertex never leaves its crease (unless
//    the edge is within the tolerance below);
//  - change a label region: the tets of `remove` must all have one label (a vertex on an
//    interface between labels is never removed; `keep` may be anywhere).
// collapse_edge() then goes through TetMesh's public edits, so the TopologyChange records it
// as consumers expect: the tets around the edge as removed, the other tets of `remove` as
// removed + added (same ids, one vertex replaced), `remove` as a removed vertex, every vertex
// of the two stars as touched. Boundary faces keep their tags (kTagCut included).
//
// Batches: consumers apply added and moved vertices before removed ones, so `remove` may be
// a parent of records made earlier in the same batch, and may itself have been added in the
// batch (a cut's new vertex): its added record stays and it is listed as removed as well.
#include <array>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise {

enum class CollapseRefusal {
  None,         // the collapse is valid
  NotAnEdge,    // dead or equal vertices, or no tet holds both
  Link,         // the link condition fails (the collapse would pinch or glue the mesh)
  Orientation,  // a rebuilt tet would be inverted or flat
  Volume,       // the rebuilt tets would not cover the star of `remove` (or nothing is left of it)
  Boundary,     // `remove` is on a corner or a curved part of the surface, or `keep` is not on its
                // flat disc (or not on its straight crease)
  Labels,       // `remove` lies on an interface between labels
};

const char* to_string(CollapseRefusal r);

// What a valid collapse does; filled by check_collapse and consumed by collapse_edge.
struct CollapsePlan {
  VertexId keep, remove;
  std::vector<TetId> removed;                   // the tets around the edge (deleted)
  std::vector<TetId> rebuilt;                   // the other tets of `remove` (kept ids, rebuilt on `keep`)
  std::vector<std::array<VertexId, 4>> tets;    // rebuilt[i]'s vertices after the collapse
  double volume_change = 0;                     // sum over labels of |volume after - before| (0 unless tolerant)
};

struct CollapseCheck {
  CollapseRefusal refusal = CollapseRefusal::NotAnEdge;
  CollapsePlan plan;
  bool ok() const { return refusal == CollapseRefusal::None; }
};

// O(size of the two stars); reads rest positions only.
//
// `tolerance` > 0: an edge no longer than tolerance x the longest edge at `remove` may also
// contract where the boundary or a label interface is curved, creased or a corner there (the
// slivers a cut leaves where its rim passes within a hair of a surface vertex sit on such
// edges, and nothing else removes them). The boundary and the interfaces then move by at most
// the edge's length: retiled boundary and interface faces must keep facing the same way
// (within 60 degrees), the star's volume may change by at most what its boundary and
// interface faces sweep over that length, and the plan reports the label volumes it moves.
// The link condition and the orientation checks stay as they are.
CollapseCheck check_collapse(const TetMesh& mesh, VertexId keep, VertexId remove, double tolerance = 0);
inline bool is_collapse_ok(const TetMesh& mesh, VertexId keep, VertexId remove, double tolerance = 0) {
  return check_collapse(mesh, keep, remove, tolerance).ok();
}
// Applies a plan that check_collapse returned ok() for on the mesh as it is now (no edit in
// between). Throws InvalidArgument for a plan that was refused.
void collapse_edge(TetMesh& mesh, const CollapsePlan& plan);
// Check then act; returns whether the mesh changed.
bool collapse_edge(TetMesh& mesh, VertexId keep, VertexId remove, double tolerance = 0);

}  // namespace incise
