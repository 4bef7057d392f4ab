#include "quality/boundary_angle.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace incise {

namespace {

std::uint64_t edge_key(VertexId a, VertexId b) {
  const std::uint64_t x = std::min(a.idx(), b.idx()), y = std::max(a.idx(), b.idx());
  return x << 32 | y;
}

// Dihedral angle of tet p at edge (p[i], p[j]), in degrees.
double dihedral_at(const std::array<Vec3, 4>& p, int i, int j) {
  int k = 0;
  while (k == i || k == j) ++k;
  const int l = 6 - i - j - k;
  const Vec3 e = (p[j] - p[i]).normalized();
  Vec3 u = p[k] - p[i], w = p[l] - p[i];
  u -= u.dot(e) * e;
  w -= w.dot(e) * e;
  return std::atan2(u.cross(w).norm(), u.dot(w)) * 180.0 / 3.14159265358979323846;
}

// Boundary edges with how many boundary faces hold them and the sum of the dihedral angles of
// the tets around them: only those held by two (manifold) have one interior angle.
struct Edge {
  int faces = 0;
  double angle = 0;
};

std::unordered_map<std::uint64_t, Edge> boundary_edge_angles(const TetMesh& mesh) {
  std::unordered_map<std::uint64_t, Edge> edges;
  for (const BoundaryFace& f : mesh.boundary_faces())
    for (int k = 0; k < 3; ++k) ++edges[edge_key(f.vertices[k], f.vertices[(k + 1) % 3])].faces;
  if (edges.empty()) return edges;
  for (TetId t : mesh.tets()) {
    const auto& v = mesh.tet_vertices(t);
    std::array<Vec3, 4> p;
    for (int k = 0; k < 4; ++k) p[k] = mesh.rest(v[k]);
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) {
        const auto it = edges.find(edge_key(v[i], v[j]));
        if (it != edges.end()) it->second.angle += dihedral_at(p, i, j);
      }
  }
  return edges;
}

}  // namespace

std::optional<BoundaryAngle> smallest_boundary_angle(const TetMesh& mesh) {
  const auto edges = boundary_edge_angles(mesh);
  std::optional<BoundaryAngle> out;
  for (const auto& [key, e] : edges)
    if (e.faces == 2 && (!out || e.angle < out->degrees))
      out = BoundaryAngle{e.angle, VertexId(static_cast<std::uint32_t>(key >> 32)),
                          VertexId(static_cast<std::uint32_t>(key & 0xffffffffu))};
  return out;
}

SharpBoundary sharp_boundary(const TetMesh& mesh, double degrees) {
  const auto edges = boundary_edge_angles(mesh);
  SharpBoundary out;
  for (const auto& [key, e] : edges) out.edges += e.faces == 2 && e.angle < degrees;
  if (out.edges == 0) return out;
  for (TetId t : mesh.tets()) {
    const auto& v = mesh.tet_vertices(t);
    bool held = false;
    for (int i = 0; i < 4 && !held; ++i)
      for (int j = i + 1; j < 4 && !held; ++j) {
        const auto it = edges.find(edge_key(v[i], v[j]));
        held = it != edges.end() && it->second.faces == 2 && it->second.angle < degrees;
      }
    if (held) out.tets.push_back(t);
  }
  return out;
}

std::vector<std::pair<VertexId, VertexId>> reflex_boundary_edges(const TetMesh& mesh, double degrees) {
  std::vector<std::pair<VertexId, VertexId>> out;
  for (const auto& [key, e] : boundary_edge_angles(mesh))
    if (e.faces == 2 && e.angle >= degrees)
      out.push_back({VertexId(static_cast<std::uint32_t>(key >> 32)), VertexId(static_cast<std::uint32_t>(key & 0xffffffffu))});
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    return std::make_pair(a.first.idx(), a.second.idx()) < std::make_pair(b.first.idx(), b.second.idx());
  });
  return out;
}

}  // namespace incise
