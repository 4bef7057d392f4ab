// The PETSc backend (sim/petsc/petsc_solver.h) in one process: the same FEM as incise's own
// solvers, so its displacement equals the direct solve's to the solver tolerance, for every
// displacement formulation, linear and corotational, static and implicit Euler, with fixed,
// prescribed and roller constraints, and after topology changes.
#include <catch2/catch.hpp>

#include <random>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "sim/fem/fem_simulation.h"
#include "sim/petsc/petsc_solver.h"
#include "tests/sim/fem_test_util.h"

using namespace incise;
using namespace incise::testing;

namespace {

// A 4 x 1 x 1 box, x = 0 clamped, the far end prescribed down, a roller (y held) on y = 0,
// forces on its top; `opt` with the backend swapped for the direct reference.
struct Pair {
  FemSimulation petsc, direct;
};

void load(const TetMesh& m, FemSimulation& s) {
  for (VertexId v : m.vertices()) {
    const Vec3 p = m.rest(v);
    if (p.x() < 1e-9) s.fix(v);
    else if (p.x() > 4 - 1e-9) s.prescribe(v, Vec3(0, 0, -0.05));
    else if (p.y() < 1e-9) s.constrain(v, 2u);
    if (p.z() > 1 - 1e-9) s.set_force(v, Vec3(0.01, 0, -0.02));
  }
}

FemSimulationOptions petsc_options(FemSimulationOptions o) {
  o.backend = StiffnessBackend::Petsc;
  o.cg.tolerance = 1e-11;
  return o;
}

FemSimulationOptions direct_options(FemSimulationOptions o) {
  o.method = SolverMethod::Direct;
  return o;
}

double relative_difference(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  REQUIRE(a.size() == b.size());
  return (a - b).norm() / std::max(b.norm(), 1e-300);
}

// One case of the formulation x kind x dynamics grid, loaded by gravity.
FemSimulationOptions case_options(Formulation f, FemKind kind, bool dynamic) {
  FemSimulationOptions o;
  o.formulation = f;
  o.kind = kind;
  o.dynamic = dynamic;
  o.dt = 0.05;
  o.gravity = Vec3(0, 0, -1);
  return o;
}

}  // namespace

TEST_CASE("petsc backend: equals the direct solve for every displacement formulation", "[fem][petsc]") {
  if (!petsc_built()) {
    CHECK_THROWS_AS(PetscSolver("", 1e-8, 100), InvalidArgument);
    return;
  }
  const TetMesh m = make_box(Vec3(4, 1, 1), {12, 3, 3});
  for (Formulation f : {Formulation::Standard, Formulation::NodalAveraged, Formulation::EdgeSmoothed})
    for (FemKind kind : {FemKind::Linear, FemKind::Corotational})
      for (bool dynamic : {false, true}) {
        FemSimulationOptions o = case_options(f, kind, dynamic);
        o.nonlinear_iterations = 2;
        FemSimulation petsc(m, table(1e4, 0.45, 10), petsc_options(o)), direct(m, table(1e4, 0.45, 10), direct_options(o));
        load(m, petsc);
        load(m, direct);
        for (int frame = 0; frame < 3; ++frame) {
          const FrameStats& st = petsc.step();
          direct.step();
          INFO("formulation " << int(f) << " kind " << int(kind) << " dynamic " << dynamic << " frame " << frame << ": "
                              << st.message);
          REQUIRE(st.info == SolveInfo::Success);
          CHECK(st.relative_residual <= 1e-10);
          // The guess is the last frame's solution: a linear static frame that repeats is solved.
          if (frame == 0) CHECK(st.iterations > 0);
          else if (kind == FemKind::Linear && !dynamic) CHECK(st.iterations == 0);
          CHECK(relative_difference(petsc.displacement(), direct.displacement()) <= 1e-8);
        }
      }
}

TEST_CASE("petsc backend: follows topology changes and new constraints", "[fem][petsc]") {
  if (!petsc_built()) return;
  TetMesh m = make_box(Vec3(4, 1, 1), {8, 2, 2});
  FemSimulationOptions o;
  o.kind = FemKind::Corotational;
  o.formulation = Formulation::NodalAveraged;
  FemSimulation petsc(m, table(1e4, 0.3), petsc_options(o)), direct(m, table(1e4, 0.3), direct_options(o));
  load(m, petsc);
  load(m, direct);
  std::mt19937 rng(7);
  for (int frame = 0; frame < 4; ++frame) {
    for (int e = 0; e < 5; ++e) random_edit(m, rng);
    const TopologyChange change = m.take_change();
    petsc.apply(change);
    direct.apply(change);
    if (frame == 2)
      for (VertexId v : m.vertices())
        if (m.rest(v).z() < 1e-9 && m.rest(v).x() > 2 - 1e-9 && m.rest(v).x() < 2 + 1e-9) {
          petsc.prescribe(v, Vec3(0, 0, 0.02));
          direct.prescribe(v, Vec3(0, 0, 0.02));
        }
    REQUIRE(petsc.step().info == SolveInfo::Success);
    direct.step();
    CHECK(relative_difference(petsc.displacement(), direct.displacement()) <= 1e-8);
  }
}

TEST_CASE("petsc backend: options pass through, and what it does not solve is refused", "[fem][petsc]") {
  if (!petsc_built()) return;
  const TetMesh m = make_box(Vec3(4, 1, 1), {8, 2, 2});
  FemSimulationOptions o;
  FemSimulation direct(m, table(1e4, 0.3), direct_options(o));
  load(m, direct);
  direct.step();
  // Another Krylov method and preconditioner by options: the same answer, more iterations; a
  // solver made after it still gets CG with GAMG (each solver has its own options).
  FemSimulationOptions p = petsc_options(o);
  p.petsc_options = "-ksp_type minres -pc_type jacobi";
  FemSimulation jacobi(m, table(1e4, 0.3), p);
  load(m, jacobi);
  const FrameStats sj = jacobi.step();
  REQUIRE(sj.info == SolveInfo::Success);
  // MINRES measures the preconditioned residual: the same tolerance is a looser one here.
  CHECK(relative_difference(jacobi.displacement(), direct.displacement()) <= 1e-6);
  FemSimulation gamg(m, table(1e4, 0.3), petsc_options(o));
  load(m, gamg);
  const FrameStats sg = gamg.step();
  REQUIRE(sg.info == SolveInfo::Success);
  CHECK(sg.iterations < sj.iterations);
  // An iteration cap too small: reported, not hidden.
  FemSimulationOptions capped = petsc_options(o);
  capped.cg.max_iterations = 2;
  FemSimulation few(m, table(1e4, 0.3), capped);
  load(m, few);
  const FrameStats sf = few.step();
  CHECK(sf.info == SolveInfo::NoConvergence);
  CHECK(sf.message.find("DIVERGED_ITS") != std::string::npos);
  // A bad option is one error naming it.
  p.petsc_options = "-ksp_type no_such_method";
  FemSimulation bad(m, table(1e4, 0.3), p);
  load(m, bad);
  CHECK_THROWS_WITH(bad.step(), Catch::Contains("no_such_method"));
  o.method = SolverMethod::Direct;
  CHECK_THROWS_AS(FemSimulation(m, table(1e4, 0.3), petsc_options(o)), InvalidArgument);
}

TEST_CASE("petsc backend: the mixed formulations by MINRES and a field split equal the direct solve", "[fem][petsc]") {
  if (!petsc_built()) return;
  const TetMesh m = make_box(Vec3(4, 1, 1), {8, 2, 2});
  for (Formulation f : {Formulation::Mixed, Formulation::MixedEdgeSmoothed})
    for (FemKind kind : {FemKind::Linear, FemKind::Corotational})
      for (bool dynamic : {false, true}) {
        const FemSimulationOptions o = case_options(f, kind, dynamic);
        FemSimulation petsc(m, table(1e4, 0.49, 10), petsc_options(o)), direct(m, table(1e4, 0.49, 10), direct_options(o));
        load(m, petsc);
        load(m, direct);
        for (int frame = 0; frame < 2; ++frame) {
          const FrameStats& st = petsc.step();
          direct.step();
          INFO("formulation " << int(f) << " kind " << int(kind) << " dynamic " << dynamic << ": " << st.message);
          REQUIRE(st.info == SolveInfo::Success);
          if (frame == 0) CHECK(st.iterations > 0);
          CHECK(relative_difference(petsc.displacement(), direct.displacement()) <= 1e-7);
        }
      }
}
