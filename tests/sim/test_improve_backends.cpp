// Local improvement feeding the backends, as after a cut: improve_local's one TopologyChange
// (flips and smoothing moves) applied to a deformed FEM simulation and spring model keeps the
// deformed shape (moved vertices take the deformation at their new rest position) and the
// next frame solves.
#include <catch2/catch.hpp>

#include "mesh/generate.h"
#include "quality/improve.h"
#include "sim/fem/fem_simulation.h"
#include "sim/springs/spring_model.h"
#include "testing/mesh_edits.h"

using namespace incise;

namespace {

// Current positions after replaying the change's moves on `pos` (indexed by VertexId).
std::vector<Vec3> replay_moves(std::vector<Vec3> pos, const TopologyChange& ch) {
  for (const VertexOrigin& o : ch.moved_vertices) {
    Vec3 p = Vec3::Zero();
    for (int k = 0; k < 4; ++k)
      if (o.parents[k].is_valid()) p += o.weights[k] * pos[o.parents[k].idx()];
    pos[o.vertex.idx()] = p;
  }
  return pos;
}

}  // namespace

TEST_CASE("improve_local's change keeps a deformed FEM and spring state consistent", "[improve][sim]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
  testing::jitter(m, 0.35, 6);
  m.discard_change();
  const MaterialTable mat(Material{1e4, 0.3, 1000});
  FemSimulationOptions fo;
  fo.gravity = Vec3(0, 0, -9.81);
  FemSimulation fem(m, mat, fo);
  SpringModel springs(m, mat);
  for (VertexId v : m.vertices())
    if (m.rest(v).z() < 1e-9) fem.fix(v);
  REQUIRE(fem.step().info == SolveInfo::Success);
  const std::vector<Vec3> before = fem.positions();

  std::vector<TetId> seeds;
  for (TetId t : m.tets())
    if ((m.rest(m.tet_vertices(t)[0]) - Vec3(0.5, 0.5, 0.5)).norm() < 0.3) seeds.push_back(t);
  const ImproveReport r = improve_local(m, seeds);
  REQUIRE(r.smoothing_moves > 0);
  const TopologyChange ch = m.take_change();
  fem.apply(ch);
  springs.apply(m, ch);
  REQUIRE_NOTHROW(m.validate());

  // Moved vertices sit where the old deformation puts their new rest position.
  const std::vector<Vec3> expected = replay_moves(before, ch), after = fem.positions();
  for (VertexId v : r.moved_vertices) CHECK((after[v.idx()] - expected[v.idx()]).norm() < 1e-12);
  REQUIRE(fem.step().info == SolveInfo::Success);
  CHECK(std::isfinite(fem.displacement().norm()));
}
