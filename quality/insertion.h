#pragma once
// Vertex insertion where flips, contraction and smoothing are stuck (Stellar's insertion,
// Klingner and Shewchuk 2007): a new vertex inside a bad tet's neighbourhood, joined to the
// boundary of a cavity of tets of one label (TetMesh::insert_in_cavity). For several start
// points (the tet's barycenter and circumcenter, its faces' centroids, its edges' midpoints)
// a cavity is grown from the tet: first the tets whose circumsphere holds the point (Bowyer-
// Watson, for the circumcenter and barycenter), then greedily across the face whose new tet is
// worst while that raises the worst new tet (and always across a face the point does not see).
// With edge_stars, more cavities start from the tets around each edge of the tet (a point
// between the edge and its ring), and from the tets around all six (from the barycenter): the
// angles at a sharp edge are shared anew by all the tets around it, where growing from the
// tet alone stops at the first boundary face the point does not see.
// The point is then placed by the smoothing ascent on the new tets (star_ascent.h). The best
// candidate is applied only when its new tets are better() than the cavity's tets; everything
// is evaluated before anything changes. The new vertex is recorded with a cavity tet holding it
// as parents. Boundary insertion (InsertionOptions::boundary_tags): a bad tet's boundary face
// takes the vertex, placed by the same ascent within the face (never across its edges), so the
// surface keeps its shape exactly and the face's three parts keep its tag.
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "mesh/tet_mesh.h"
#include "quality/improve_scope.h"

namespace incise {

struct InsertionOptions {
  int max_cavity = 16;  // most tets one insertion replaces
  int iterations = 16;  // ascent steps placing the point
  bool edge_stars = true;  // also cavities seeded with the stars of the tet's edges (see above)
  // Boundary faces of these tags may take the new vertex (split in three, exactly in their
  // plane); empty: interior insertion only.
  std::function<bool(std::uint16_t)> boundary_tags;
  bool* growth_refused = nullptr;  // set when a candidate was refused only for the growth cap
};

struct InsertionOutcome {
  VertexId vertex;
  bool on_boundary = false;
  std::vector<TetId> removed, added;
};

std::optional<InsertionOutcome> improve_by_insertion(TetMesh& mesh, TetId t, const ImproveScope& scope,
                                                     const InsertionOptions& opt = {});

}  // namespace incise
