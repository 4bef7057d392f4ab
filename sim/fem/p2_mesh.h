#pragma once
// P2Mesh: the 10-node (quadratic) view of a TetMesh. The corner nodes are the mesh's vertex
// slots (node v is VertexId v, 0 <= v < corner_slots), one mid-edge node per edge of a live tet
// follows (node corner_slots + e for edge e). The mid-edge nodes live here, beside the mesh;
// the mesh itself stays linear. A rebuild is O(mesh): quadratic tets are for references and
// offline accuracy, not for cutting (docs/solver.md#quadratic-tets).
//
// Node order per tet is VTK's VTK_QUADRATIC_TETRA (24), which is also CalculiX's / Abaqus'
// C3D10 order: corners 0..3, then the mid-edge nodes of (0,1), (1,2), (0,2), (0,3), (1,3), (2,3).
#include <array>
#include <cstdint>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise {

// The local corners of mid-edge node 4 + k.
inline constexpr std::array<std::array<int, 2>, 6> kP2Edges{{{0, 1}, {1, 2}, {0, 2}, {0, 3}, {1, 3}, {2, 3}}};

struct P2Mesh {
  std::size_t corner_slots = 0;                      // the mesh's vertex_capacity() when built
  std::vector<std::array<std::uint32_t, 2>> edges;   // per mid-edge node: its edge's vertex ids (lower first)
  std::vector<std::array<std::uint32_t, 10>> tets;   // per TetId: its 10 nodes (dead slots: unused)
  std::vector<std::uint8_t> alive;                   // per TetId
  std::size_t num_nodes() const { return corner_slots + edges.size(); }
  bool is_mid(std::size_t node) const { return node >= corner_slots; }
  // Rest position of a node (mid-edge: the midpoint of its straight edge).
  Vec3 rest(const TetMesh& mesh, std::size_t node) const;
};

// O(mesh). Edges are numbered in the order the live tets first meet them.
P2Mesh make_p2_mesh(const TetMesh& mesh);

// `field` (3 per corner slot, as FemSimulation's displacement) extended to every P2 node: the
// mid-edge nodes get the mean of their edge's ends (a linear field, exact for one).
Eigen::VectorXd p2_from_corners(const P2Mesh& p2, const Eigen::VectorXd& field);

}  // namespace incise
