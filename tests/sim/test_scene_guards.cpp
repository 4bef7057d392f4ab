// Solves that cannot lie: a solve whose residual or solution is not finite is never reported as
// converged.
#include <catch2/catch.hpp>

#include <cmath>

#include "mesh/generate.h"
#include "sim/fem_simulation.h"

using namespace incise;

TEST_CASE("a solve whose residual is not finite is not converged", "[fem][guards]") {
  // Forces of 1e200 on the tip of a clamped beam: the displacement (~1e200) is finite, but the
  // norms of the residual and of the right-hand side overflow, so nothing vouches for it.
  auto solve = [](double force, SolverMethod method) {
    const TetMesh m = make_box(Vec3(4, 1, 1), {8, 2, 2});
    FemSimulationOptions o;
    o.method = method;
    FemSimulation sim(m, MaterialTable(Material{1e4, 0.3, 1}), o);
    for (VertexId v : m.vertices()) {
      if (m.rest(v).x() == 0) sim.fix(v);
      if (m.rest(v).x() == 4) sim.set_force(v, Vec3(0, 0, -force));
    }
    return sim.step();
  };
  for (SolverMethod method : {SolverMethod::Direct, SolverMethod::Cg}) {
    const FrameStats ok = solve(1, method);
    CHECK(ok.info == SolveInfo::Success);
    CHECK(std::isfinite(ok.relative_residual));
    const FrameStats huge = solve(1e200, method);
    CHECK(huge.info == SolveInfo::NumericalIssue);
    CHECK_FALSE(huge.message.empty());
  }
}
