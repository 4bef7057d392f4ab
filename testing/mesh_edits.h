#pragma once
// Shared by tests and benchmarks: seeded random mesh edits and vertex jitter. One place, so
// every locality / local-update test drives the mesh the same way.
#include <algorithm>
#include <random>
#include <vector>

#include "mesh/edge_collapse.h"
#include "mesh/errors.h"
#include "mesh/tet_mesh.h"
#include "testing/draws.h"

namespace incise::testing {

inline TetId random_tet(const TetMesh& m, std::mt19937& rng) {
  std::uniform_int_distribution<std::uint32_t> pick(0, static_cast<std::uint32_t>(m.tet_capacity() - 1));
  for (;;) {
    TetId t(pick(rng));
    if (m.is_alive(t)) return t;
  }
}

// One random edit: split an edge / face / tet at a random interior point, or a 2-3, 3-2 or
// 4-4 flip where the check allows it, or (allow_remove) remove a boundary tet. Returns whether
// the mesh changed; an edit the mesh refuses leaves it unchanged.
inline bool random_edit(TetMesh& m, std::mt19937& rng, bool allow_remove = false) {
  std::uniform_real_distribution<double> u(0.25, 0.75);
  std::uniform_int_distribution<int> op(0, allow_remove ? 6 : 5), loc(0, 3);
  const TetId t = random_tet(m, rng);
  const auto v = m.tet_vertices(t);
  switch (op(rng)) {
    case 0: {
      int i = loc(rng), j = (i + 1 + loc(rng) % 3) % 4;
      m.split_edge(v[i], v[j], u(rng));
      return true;
    }
    case 1: {
      double a = u(rng), b = u(rng), c = u(rng), s = a + b + c;
      m.split_face(t, loc(rng), {a / s, b / s, c / s});
      return true;
    }
    case 2: {
      double w[4], s = 0;
      for (double& x : w) s += (x = u(rng));
      m.split_tet(t, {w[0] / s, w[1] / s, w[2] / s, w[3] / s});
      return true;
    }
    case 3: {
      int f = loc(rng);
      if (!m.is_flip23_ok(t, f)) return false;
      m.flip23(t, f);
      return true;
    }
    case 4: {
      int i = loc(rng), j = (i + 1 + loc(rng) % 3) % 4;
      if (!m.is_flip32_ok(v[i], v[j])) return false;
      m.flip32(v[i], v[j]);
      return true;
    }
    case 5: {
      int i = loc(rng), j = (i + 1 + loc(rng) % 3) % 4, k = loc(rng) % 2;
      if (!m.is_flip44_ok(v[i], v[j], k)) return false;
      m.flip44(v[i], v[j], k);
      return true;
    }
    default: {  // a boundary tet, so the mesh mostly stays in one piece
      bool boundary = false;
      for (int f = 0; f < 4; ++f) boundary = boundary || !m.neighbor(t, f).is_valid();
      if (!boundary || m.num_tets() < 20) return false;
      m.remove_tet(t);
      return true;
    }
  }
}

// One random edge contraction: a random edge of a random tet, either way, where
// check_collapse allows it and `removable(v)` says the vertex that goes may go (callers keep the
// vertices added earlier in the same batch, see mesh/edge_collapse.h). Returns whether the mesh
// changed.
template <class Removable>
bool random_collapse(TetMesh& m, std::mt19937& rng, Removable removable) {
  const TetId t = random_tet(m, rng);
  const auto v = m.tet_vertices(t);
  const int i = static_cast<int>(rng() % 4), j = (i + 1 + static_cast<int>(rng() % 3)) % 4;
  if (!removable(v[j])) return false;
  return collapse_edge(m, v[i], v[j]);
}

// One random cavity insertion (TetMesh::insert_in_cavity): a random interior point of a random
// tet, the cavity that tet plus a random subset of its same-label neighbours (and of theirs).
// Returns whether the mesh took it.
inline bool random_cavity_insertion(TetMesh& m, std::mt19937& rng) {
  const TetId t = random_tet(m, rng);
  std::vector<TetId> cavity = {t};
  for (std::size_t i = 0; i < cavity.size() && i < 3; ++i)
    for (int f = 0; f < 4; ++f) {
      const TetId n = m.neighbor(cavity[i], f);
      if (n.is_valid() && m.label(n) == m.label(t) && rng() % 2 &&
          std::find(cavity.begin(), cavity.end(), n) == cavity.end())
        cavity.push_back(n);
    }
  std::uniform_real_distribution<double> u(0.25, 0.75);
  std::array<double, 4> w;
  double s = 0;
  for (double& x : w) s += (x = u(rng));
  Vec3 p = Vec3::Zero();
  for (int k = 0; k < 4; ++k) p += (w[k] /= s) * m.rest(m.tet_vertices(t)[k]);
  if (!m.is_cavity_insertion_ok(cavity, p)) return false;
  m.insert_in_cavity(cavity, m.tet_vertices(t), w);
  return true;
}

inline std::vector<std::uint8_t> boundary_vertices(const TetMesh& m) {
  std::vector<std::uint8_t> on(m.vertex_capacity(), 0);
  for (const auto& f : m.boundary_faces())
    for (VertexId v : f.vertices) on[v.idx()] = 1;
  return on;
}

// Moves interior vertices by up to `amount` of their shortest incident edge in random
// directions, undoing any move that would invert a tet: breaks the coplanarities of
// structured meshes so flips apply and shapes vary.
inline void jitter(TetMesh& m, double amount, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  const auto on_boundary = boundary_vertices(m);
  for (VertexId v : m.vertices()) {
    if (on_boundary[v.idx()]) continue;
    double h = 1e300;
    for (TetId t : m.incident_tets(v))
      for (VertexId w : m.tet_vertices(t))
        if (w != v) h = std::min(h, (m.rest(w) - m.rest(v)).norm());
    const Vec3 old = m.rest(v);
    m.set_rest(v, old + amount * h * draw_vec3(u, rng));
    for (TetId t : m.incident_tets(v))
      if (m.volume(t) <= 0) m.set_rest(v, old);
  }
}

// A crack along the faces between the tets whose centroid lies below `at` on `axis` and those
// above it, opened at the vertices there whose rest position `opens` accepts (the faces with
// such a vertex open; a vertex it refuses beside them is on the crack's front): those vertices
// are duplicated (recorded as added vertices with one parent) and the upper-side tets moved
// onto the duplicates. A stand-in for a scalpel cut in sim and quality tests and benchmarks
// (cut/ has the real one). Returns the vertices duplicated.
template <class Opens>
std::size_t crack_where(TetMesh& m, int axis, double at, Opens opens) {
  auto centre = [&](TetId t) {
    Vec3 c = Vec3::Zero();
    for (VertexId w : m.tet_vertices(t)) c += m.rest(w) / 4;
    return c;
  };
  std::vector<VertexId> on;
  for (VertexId v : m.vertices()) {
    if (!opens(m.rest(v))) continue;
    bool below = false, above = false;
    for (TetId t : m.incident_tets(v)) (centre(t)[axis] < at ? below : above) = true;
    if (below && above) on.push_back(v);
  }
  std::size_t n = 0;
  for (VertexId v : on) {
    std::vector<TetId> upper;
    for (TetId t : m.incident_tets(v))
      if (centre(t)[axis] >= at) upper.push_back(t);
    const VertexId parents[1] = {v};
    const double weights[1] = {1.0};
    const VertexId d = m.add_vertex_interpolated(parents, weights);
    for (TetId t : upper) m.replace_vertex(t, v, d);
    ++n;
  }
  return n;
}

// crack_where() above `from` on axis `up`: crack deeper by calling again with a lower `from`.
inline std::size_t crack(TetMesh& m, int axis, double at, int up, double from) {
  return crack_where(m, axis, at, [&](const Vec3& p) { return p[up] > from; });
}

}  // namespace incise::testing
