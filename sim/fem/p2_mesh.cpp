#include "sim/fem/p2_mesh.h"

#include <unordered_map>

namespace incise {

Vec3 P2Mesh::rest(const TetMesh& mesh, std::size_t node) const {
  if (node < corner_slots) return mesh.rest(VertexId(std::uint32_t(node)));
  const auto& e = edges[node - corner_slots];
  return 0.5 * (mesh.rest(VertexId(e[0])) + mesh.rest(VertexId(e[1])));
}

P2Mesh make_p2_mesh(const TetMesh& mesh) {
  P2Mesh p2;
  p2.corner_slots = mesh.vertex_capacity();
  p2.tets.resize(mesh.tet_capacity());
  p2.alive.assign(mesh.tet_capacity(), 0);
  std::unordered_map<std::uint64_t, std::uint32_t> index;
  index.reserve(mesh.num_tets() * 2);
  for (TetId t : mesh.tets()) {
    const auto& v = mesh.tet_vertices(t);
    auto& nodes = p2.tets[t.idx()];
    for (int k = 0; k < 4; ++k) nodes[std::size_t(k)] = v[std::size_t(k)].idx();
    for (std::size_t k = 0; k < 6; ++k) {
      std::uint32_t a = v[std::size_t(kP2Edges[k][0])].idx(), b = v[std::size_t(kP2Edges[k][1])].idx();
      if (a > b) std::swap(a, b);
      const std::uint64_t key = (std::uint64_t(a) << 32) | b;
      const auto [it, added] = index.try_emplace(key, std::uint32_t(p2.edges.size()));
      if (added) p2.edges.push_back({a, b});
      nodes[4 + k] = std::uint32_t(p2.corner_slots + it->second);
    }
    p2.alive[t.idx()] = 1;
  }
  return p2;
}

Eigen::VectorXd p2_from_corners(const P2Mesh& p2, const Eigen::VectorXd& field) {
  Eigen::VectorXd out = Eigen::VectorXd::Zero(3 * Eigen::Index(p2.num_nodes()));
  const Eigen::Index nc = std::min<Eigen::Index>(field.size(), 3 * Eigen::Index(p2.corner_slots));
  out.head(nc) = field.head(nc);
  for (std::size_t e = 0; e < p2.edges.size(); ++e) {
    const auto& ab = p2.edges[e];
    const Eigen::Index a = 3 * Eigen::Index(ab[0]), b = 3 * Eigen::Index(ab[1]);
    if (a + 3 <= field.size() && b + 3 <= field.size())
      out.segment<3>(3 * Eigen::Index(p2.corner_slots + e)) = 0.5 * (field.segment<3>(a) + field.segment<3>(b));
  }
  return out;
}

}  // namespace incise
