#pragma once
// Connectivity of a tet mesh: components of tets (through shared faces) and the topology
// of the boundary surface (open / non-manifold / mis-oriented edges, non-manifold
// vertices, shells). Both are O(mesh) (the boundary part sorts the boundary edges).
#include <cstddef>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise {

struct TetComponents {
  std::size_t count = 0;
  // Component index per tet id (size tet_capacity(); dead tets get -1). Components are
  // numbered in order of their lowest tet id.
  std::vector<int> of_tet;
  std::vector<std::size_t> sizes;  // tets per component
};
// Components of tets connected through shared faces (neighbor()); tets touching only at an
// edge or a vertex are in different components.
TetComponents tet_components(const TetMesh& mesh);

struct BoundaryTopology {
  std::size_t faces = 0;                  // boundary faces
  std::size_t edges = 0;                  // distinct boundary edges
  std::size_t open_edges = 0;             // in exactly one boundary face
  std::size_t non_manifold_edges = 0;     // in three or more boundary faces
  std::size_t misoriented_edges = 0;      // in two faces that traverse it the same way
  std::size_t non_manifold_vertices = 0;  // boundary faces around it form 2+ fans
  std::size_t shells = 0;                 // boundary faces connected through shared edges
  bool closed() const { return open_edges == 0; }
  bool manifold() const { return non_manifold_edges == 0 && non_manifold_vertices == 0; }
  bool oriented() const { return misoriented_edges == 0; }
};
// A vertex is non-manifold when its boundary faces, linked across its manifold edges, do
// not form a single fan: two tets sharing only a vertex, or the endpoints of a
// non-manifold edge.
BoundaryTopology boundary_topology(const TetMesh& mesh);

}  // namespace incise
