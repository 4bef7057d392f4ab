#pragma once
// The axis-aligned box of a mesh's live vertices at their rest positions: one place for what
// scenes, solvers, the viewer and `incise info` measure the body by.
#include <limits>

#include "mesh/tet_mesh.h"

namespace incise {

struct RestBounds {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = -lo;
  bool empty() const { return !(hi.x() >= lo.x()); }  // no vertex
  Vec3 size() const { return empty() ? Vec3::Zero() : Vec3(hi - lo); }
  Vec3 center() const { return empty() ? Vec3::Zero() : Vec3(0.5 * (lo + hi)); }
};

// O(live vertices), isolated ones included.
RestBounds rest_bounds(const TetMesh& mesh);

}  // namespace incise
