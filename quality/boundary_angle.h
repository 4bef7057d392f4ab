#pragma once
// What the boundary allows: the smallest interior angle of the domain at a boundary edge,
// measured as the sum of the dihedral angles of the tets around that edge. Those dihedral
// angles add up to it in every tet mesh of the same surface, so the smallest of them is at
// most this angle: no improvement that keeps the surface can lift the worst dihedral angle
// above it (the sample liver's sharpest edge caps it just under the 35-degree target).
#include <optional>
#include <utility>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise {

struct BoundaryAngle {
  double degrees = 180;       // smallest interior angle at a boundary edge
  VertexId a, b;              // that edge
};

// nullopt for a mesh without manifold boundary edges. O(mesh).
std::optional<BoundaryAngle> smallest_boundary_angle(const TetMesh& mesh);

// The tets the boundary forces below an angle: every tet around a boundary edge whose interior
// angle is under `degrees` has a dihedral angle under it there, in any mesh of that surface.
struct SharpBoundary {
  std::size_t edges = 0;      // manifold boundary edges with an interior angle under `degrees`
  std::vector<TetId> tets;    // the tets around them, each once, in id order
};
SharpBoundary sharp_boundary(const TetMesh& mesh, double degrees);

// Manifold boundary edges whose interior angle is at least `degrees`, each (smaller id, larger
// id), sorted: near 360, the front of a cut that ends inside the body, where its two sides lie
// folded onto each other. O(mesh).
std::vector<std::pair<VertexId, VertexId>> reflex_boundary_edges(const TetMesh& mesh, double degrees);

}  // namespace incise
