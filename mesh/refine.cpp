#include "mesh/refine.h"

#include <algorithm>
#include <unordered_map>

#include "mesh/errors.h"

namespace incise {

namespace {

std::uint64_t edge_key(VertexId a, VertexId b) {
  const std::uint64_t lo = std::min(a.idx(), b.idx()), hi = std::max(a.idx(), b.idx());
  return lo << 32 | hi;
}

double signed_volume(const TetMesh& m, const std::array<VertexId, 4>& v) {
  const Vec3 a = m.rest(v[0]);
  return (m.rest(v[1]) - a).cross(m.rest(v[2]) - a).dot(m.rest(v[3]) - a);
}

}  // namespace

TetMesh refine_uniform(const TetMesh& in) {
  if (in.num_vertices() != in.vertex_capacity() || in.num_tets() != in.tet_capacity())
    throw InvalidArgument("refine_uniform: the mesh has dead slots; compact() it first");
  TetMesh out;
  out.reserve(in.num_vertices() * 8, in.num_tets() * 8);  // V + E, E is about 7 V on tet meshes
  for (VertexId v : in.vertices()) out.add_vertex(in.rest(v));
  std::unordered_map<std::uint64_t, VertexId> midpoint;
  midpoint.reserve(in.num_tets() * 2);
  auto mid = [&](VertexId a, VertexId b) {
    auto [it, added] = midpoint.try_emplace(edge_key(a, b));
    if (added) it->second = out.add_vertex(0.5 * (in.rest(a) + in.rest(b)));
    return it->second;
  };
  for (TetId t : in.tets()) {
    const auto pv = in.tet_vertices(t);
    // Node k < 4: corner k; node 4 + e: midpoint of the edge e = (i, j), i < j, in lexicographic order.
    static constexpr int kEdge[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
    std::array<VertexId, 10> node;
    // Which parent corners each node lies on (bit per corner): a child face is on parent face f
    // when none of its three nodes involves corner f.
    std::array<unsigned, 10> corners;
    for (int k = 0; k < 4; ++k) {
      node[k] = pv[k];
      corners[k] = 1u << k;
    }
    for (int e = 0; e < 6; ++e) {
      node[4 + e] = mid(pv[kEdge[e][0]], pv[kEdge[e][1]]);
      corners[4 + e] = 1u << kEdge[e][0] | 1u << kEdge[e][1];
    }
    auto m = [&](int i, int j) { return 4 + int(std::find_if(std::begin(kEdge), std::end(kEdge), [&](const int* e) {
                                             return e[0] == std::min(i, j) && e[1] == std::max(i, j);
                                           }) - std::begin(kEdge)); };
    std::vector<std::array<int, 4>> kids = {
        {0, m(0, 1), m(0, 2), m(0, 3)}, {m(0, 1), 1, m(1, 2), m(1, 3)}, {m(0, 2), m(1, 2), 2, m(2, 3)}, {m(0, 3), m(1, 3), m(2, 3), 3}};
    // The octahedron: split along its shortest diagonal (the best-shaped children; Bey 1995).
    static constexpr int kDiag[3][2][2] = {{{0, 1}, {2, 3}}, {{0, 2}, {1, 3}}, {{0, 3}, {1, 2}}};
    int best = 0;
    double best_len = 1e300;
    for (int d = 0; d < 3; ++d) {
      const double len = (out.rest(node[m(kDiag[d][0][0], kDiag[d][0][1])]) - out.rest(node[m(kDiag[d][1][0], kDiag[d][1][1])])).squaredNorm();
      if (len < best_len) best_len = len, best = d;
    }
    const int a = m(kDiag[best][0][0], kDiag[best][0][1]), b = m(kDiag[best][1][0], kDiag[best][1][1]);
    std::vector<int> ring;
    for (int e = 4; e < 10; ++e)
      if (e != a && e != b) ring.push_back(e);
    // Order the equator so that neighbours share a parent corner (octahedron edges).
    for (std::size_t i = 1; i + 1 < ring.size(); ++i)
      for (std::size_t j = i; j < ring.size(); ++j)
        if (corners[std::size_t(ring[i - 1])] & corners[std::size_t(ring[j])]) {
          std::swap(ring[i], ring[j]);
          break;
        }
    for (std::size_t i = 0; i < 4; ++i) kids.push_back({a, b, ring[i], ring[(i + 1) % 4]});
    for (auto& k : kids) {
      std::array<VertexId, 4> v{node[std::size_t(k[0])], node[std::size_t(k[1])], node[std::size_t(k[2])], node[std::size_t(k[3])]};
      if (signed_volume(out, v) < 0) {
        std::swap(v[2], v[3]);
        std::swap(k[2], k[3]);
      }
      const TetId c = out.add_tet(v[0], v[1], v[2], v[3], in.label(t));
      for (int f = 0; f < 4; ++f) {
        unsigned used = 0;
        for (int l : kFaceLocal[std::size_t(f)]) used |= corners[std::size_t(k[std::size_t(l)])];
        for (int pf = 0; pf < 4; ++pf)
          if (!(used >> pf & 1u) && !in.neighbor(t, pf).is_valid()) out.set_face_tag(c, f, in.face_tag(t, pf));
      }
    }
  }
  out.discard_change();
  return out;
}

}  // namespace incise
