// Cuts through tissue that moves while it is cut (CutOptions::material_frame): the blade is
// mapped into the rest shape through the local deformation, so a blade that follows the tissue
// cuts the tissue where the blade is in the tissue, whatever the tissue did meanwhile.
#include <catch2/catch.hpp>

#include <cmath>

#include "cut/cutter.h"
#include "mesh/generate.h"
#include "quality/components.h"
#include "tests/cut/cut_checks.h"

using namespace incise;
using namespace incise::testing;

namespace {

// The body turns about the z-axis through (1, 0.5, 0.5) by 2 degrees a step and drifts along x;
// the blade is held still in the tissue: across it at x = 1.03, going down through it.
struct Moving {
  int steps = 10;
  Eigen::Matrix3d rotation(int k) const {
    return Eigen::AngleAxisd(k * 2.0 * std::acos(-1.0) / 180.0, Vec3::UnitZ()).toRotationMatrix();
  }
  Vec3 at(int k, const Vec3& rest) const {
    const Vec3 c(1, 0.5, 0.5);
    return rotation(k) * (rest - c) + c + Vec3(0.1 * k, 0, 0);
  }
  BladeSegment rest_blade(int k) const {
    const double z = 1.3 - 1.6 * k / steps;
    return {Vec3(1.03, -0.5, z), Vec3(1.03, 1.5, z)};
  }
};

struct Result {
  std::size_t tets = 0, parts = 0;
  double max_off = 0;  // largest distance of a cut face's rest corner from the plane x = 1.03
};

Result cut_moving(bool material, bool move) {
  TetMesh m = make_box(Vec3(2, 1, 1), {8, 4, 4});
  m.discard_change();
  const auto vol0 = label_volumes(m);
  CutOptions opt;
  opt.material_frame = material;
  Cutter cutter(m, opt);
  const Moving mv;
  auto world = [&](int k, const BladeSegment& b) {
    return move ? BladeSegment{mv.at(k, b.a), mv.at(k, b.b)} : b;
  };
  cutter.start(world(0, mv.rest_blade(0)));
  double moved = 0;
  for (int k = 1; k <= mv.steps; ++k) {
    // Rigid motion is affine: every vertex's current position follows from its rest one,
    // the cutter's new vertices included.
    auto pos = [&](VertexId v) { return move ? mv.at(k, m.rest(v)) : m.rest(v); };
    moved += cutter.advance(world(k, mv.rest_blade(k)), pos).improve.volume_change;
    check_cut_invariants(m, vol0, 1e-9, moved);
  }
  auto pos = [&](VertexId v) { return move ? mv.at(mv.steps, m.rest(v)) : m.rest(v); };
  cutter.finish(pos);
  Result r{m.num_tets(), tet_components(m).count, 0};
  for (const auto& f : m.boundary_faces())
    if (f.tag == kTagCut)
      for (VertexId v : f.vertices) r.max_off = std::max(r.max_off, std::abs(m.rest(v).x() - 1.03));
  return r;
}

}  // namespace

TEST_CASE("moving tissue: a blade held still in turning tissue cuts one flat sheet in the rest shape",
          "[cut][moving]") {
  const Result still = cut_moving(false, false);
  REQUIRE(still.parts == 2);
  const Result material = cut_moving(true, true);
  CHECK(material.parts == 2);
  // On the plane up to the snap distance (0.05 of an edge of 0.25-0.5).
  CHECK(material.max_off <= 0.05 * 0.5);
  CHECK(double(material.tets) == Approx(double(still.tets)).epsilon(0.05));
  // Cut in the current shape instead, the world-space sheet turns away from the tissue's plane.
  const Result current = cut_moving(false, true);
  CHECK(current.max_off > 0.05);
}
