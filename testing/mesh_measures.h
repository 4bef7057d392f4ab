#pragma once
// Shared by tests: what an edit must keep, measured from scratch (volume per label, boundary
// area per tag), so the checks do not trust the code they check.
#include <cstdint>
#include <map>

#include <catch2/catch.hpp>

#include "mesh/tet_mesh.h"

namespace incise::testing {

inline std::map<int, double> label_volumes(const TetMesh& m) {
  std::map<int, double> v;
  for (TetId t : m.tets()) v[m.label(t)] += m.volume(t);
  return v;
}

inline std::map<std::uint16_t, double> tag_areas(const TetMesh& m) {
  std::map<std::uint16_t, double> a;
  for (const auto& f : m.boundary_faces())
    a[f.tag] += 0.5 * (m.rest(f.vertices[1]) - m.rest(f.vertices[0])).cross(m.rest(f.vertices[2]) - m.rest(f.vertices[0])).norm();
  return a;
}

// The vertex at rest position p (to 1e-9); fails the test when there is none.
inline VertexId vertex_at(const TetMesh& m, const Vec3& p) {
  for (VertexId v : m.vertices())
    if ((m.rest(v) - p).norm() < 1e-9) return v;
  FAIL("no vertex at " << p.transpose());
  return {};
}

}  // namespace incise::testing
