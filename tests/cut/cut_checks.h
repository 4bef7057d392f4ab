#pragma once
// Shared by the cut tests and the torture run: the invariants every cut step must keep.
#include <catch2/catch.hpp>

#include <cstdlib>
#include <iostream>
#include <map>

#include "cut/cutter.h"
#include "mesh/tet_mesh.h"
#include "quality/components.h"

namespace incise::testing {

inline std::map<int, double> label_volumes(const TetMesh& m) {
  std::map<int, double> v;
  for (TetId t : m.tets()) v[m.label(t)] += m.volume(t);
  return v;
}

inline double tagged_area(const TetMesh& m, std::uint16_t tag) {
  double a = 0;
  for (const auto& f : m.boundary_faces())
    if (f.tag == tag)
      a += 0.5 * (m.rest(f.vertices[1]) - m.rest(f.vertices[0])).cross(m.rest(f.vertices[2]) - m.rest(f.vertices[0])).norm();
  return a;
}

// validate() with orientation and a closed manifold boundary, and every label's volume
// unchanged (subdivision mode) to `rel` of the total, plus `moved`: what the improvement's
// tolerance-mode contractions say they moved (their reports' volume_change, summed).
inline void check_cut_invariants(const TetMesh& m, const std::map<int, double>& vol0, double rel = 1e-9,
                                 double moved = 0) {
  REQUIRE_NOTHROW(m.validate({true, true}));
  double total = 0;
  for (const auto& [l, v] : vol0) total += v;
  const auto vol = label_volumes(m);
  REQUIRE(vol.size() == vol0.size());
  for (const auto& [l, v] : vol0) REQUIRE(std::abs(vol.at(l) - v) <= rel * total + moved);
}

}  // namespace incise::testing
