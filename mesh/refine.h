#pragma once
// Uniform refinement: every tet split 1:8 (Bey's red refinement: four corner tets and the
// inner octahedron cut along its shortest diagonal). A mesh refined k times has edges 2^-k as
// long and stays conforming, so a field on it converges like the element's order; incise trade
// solves its reference on it. Region labels are inherited; a boundary face's tag goes to its
// four children. Vertex ids of the input (a compact mesh: no dead slots) are kept; the edge
// midpoints follow.
#include "mesh/tet_mesh.h"

namespace incise {

// Throws InvalidArgument for a mesh with dead vertex or tet slots (compact() it first).
TetMesh refine_uniform(const TetMesh& mesh);

}  // namespace incise
