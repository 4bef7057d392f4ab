#pragma once
// Slivers across thin parts. A tet with two vertices on boundary faces that face away from
// each other (outward normals more than 120 degrees apart) lies across a part of the body:
// a layer between two cut sheets, or between a cut and the surface. Measured between those
// two vertices along the faces' mean normal, the part's thickness there bounds how wide the
// tet can be across it (it must be positive: the two sides of one cut lie on each other in
// the rest shape, and a tet around the cut's front that reaches both is not across a part); where it is under `ratio` of the tet's longest edge, the tet is flat
// at this size, and only smaller tets (refining the part down to its thickness, faces on both
// sides included) would be better. Flips, smoothing and insertion at the tet's size do not
// lift it. A heuristic, unlike the bound of a sharp boundary edge (quality/boundary_angle.h):
// it says where the mesh is too coarse for the body, not what every mesh must contain.
#include <span>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise {

struct ThinPartOptions {
  double sliver_degrees = 10;  // slivers_across_thin_parts: the tets whose smallest dihedral angle is under this
  double ratio = 0.25;         // thickness across the part over the tet's longest edge
  double opposed_cos = -0.5;   // two boundary faces face away from each other below this cosine
};

// Of `candidates` (e.g. the slivers a quality report counted), those across a part thinner than
// `ratio` of their longest edge, in the candidates' order (sliver_degrees is not read). O(mesh)
// for the boundary, then a few face pairs per candidate.
std::vector<TetId> across_thin_parts(const TetMesh& mesh, std::span<const TetId> candidates,
                                     const ThinPartOptions& options = {});

// The same for every sliver of the mesh (rest shape, under sliver_degrees), in id order,
// leaving out those in `exclude` (sorted; e.g. sharp_boundary(...).tets, the slivers the
// surface forces anyway).
std::vector<TetId> slivers_across_thin_parts(const TetMesh& mesh, const ThinPartOptions& options = {},
                                             const std::vector<TetId>& exclude = {});

}  // namespace incise
