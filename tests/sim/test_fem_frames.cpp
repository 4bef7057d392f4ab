// Frames and budgets: per-frame setup products, resuming an interrupted CG, budgeted frames
// that add up to one uninterrupted solve, and the predicting warm start.
#include <catch2/catch.hpp>

#include <cmath>

#include "mesh/generate.h"
#include "sim/linalg/cg_solver.h"
#include "sim/fem/fem_model.h"
#include "sim/fem/fem_simulation.h"
#include "tests/sim/fem_test_util.h"

using namespace incise;
using namespace incise::testing;

namespace {

// Counts products, so the setup cost of a solve can be checked.
struct Counting : LinearOperator {
  const LinearOperator& a;
  mutable int products = 0;
  explicit Counting(const LinearOperator& op) : a(op) {}
  Eigen::Index rows() const override { return a.rows(); }
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const override {
    ++products;
    a.multiply(x, y);
  }
  const Eigen::VectorXd& diagonal() const override { return a.diagonal(); }
  const std::vector<Eigen::Matrix3d>& diagonal_blocks() const override { return a.diagonal_blocks(); }
};

// A cantilever fixed at x = 0 with a tip probe (prescribed) and a traction.
struct ProbedCantilever {
  TetMesh mesh = make_box(Vec3(4, 1, 1), {16, 4, 4});
  std::vector<VertexId> tip;
  void setup(FemSimulation& sim) {
    tip.clear();
    for (VertexId v : mesh.vertices()) {
      if (mesh.rest(v).x() < 1e-9) sim.fix(v);
      if (mesh.rest(v).x() > 4 - 1e-9) tip.push_back(v);
    }
    add_face_traction(mesh, sim, 2, 1, Vec3(0, 0, -200), 1e-9);
  }
  void probe(FemSimulation& sim, const Vec3& d) {
    for (VertexId v : tip) sim.prescribe(v, d);
  }
};

}  // namespace

TEST_CASE("CG setup costs one product, a resume none", "[fem][frames]") {
  ProbedCantilever c;
  FemSimulation sim(c.mesh, table(1e5, 0.3));
  c.setup(sim);
  c.probe(sim, Vec3(0, 0, -0.1));
  Counting op(sim.model());
  Eigen::VectorXd b = Eigen::VectorXd::Zero(op.rows());
  b[3 * c.tip[0].idx()] = 1;  // a force somewhere
  Eigen::VectorXd x = Eigen::VectorXd::Zero(op.rows());
  for (VertexId v : c.tip) x[3 * v.idx() + 2] = -0.1;
  ConjugateGradient cg;
  cg.compute(op, &sim.free_mask());
  // Cold start with prescribed values: A x_kept only.
  cg.set_max_iterations(30);
  cg.solve_with_guess(b, x);
  CHECK(cg.info() == SolveInfo::NoConvergence);
  CHECK(op.products == cg.iterations() + 1);
  // Same problem, same x: resumes, no setup product.
  op.products = 0;
  CHECK(cg.can_resume(b, x));
  cg.solve_with_guess(b, x);
  CHECK(cg.stats().resumed);
  CHECK(op.products == cg.iterations());
  // A new load, same kept values: A x_kept is cached, A x_free is the one setup product.
  b *= 2;
  op.products = 0;
  cg.set_max_iterations(10000);
  cg.solve_with_guess(b, x);
  CHECK(!cg.stats().resumed);
  CHECK(cg.info() == SolveInfo::Success);
  CHECK(op.products == cg.iterations() + 1);
  // After invalidate() (the operator changed in place) A x_kept is recomputed.
  cg.invalidate();
  b *= 0.5;
  op.products = 0;
  cg.solve_with_guess(b, x);
  CHECK(op.products == cg.iterations() + 2);
}

TEST_CASE("budgeted frames on an unchanged problem add up to one uninterrupted solve", "[fem][frames]") {
  for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
    for (Preconditioner pc : {Preconditioner::Jacobi, Preconditioner::BlockJacobi}) {
      ProbedCantilever c;
      FemSimulationOptions opt;
      opt.kind = kind;
      opt.cg.tolerance = 1e-9;
      opt.cg.preconditioner = pc;
      FemSimulation ref(c.mesh, table(1e5, 0.45), opt);
      c.setup(ref);
      c.probe(ref, Vec3(0, 0, -0.2));
      const FrameStats one = ref.step();
      REQUIRE(one.info == SolveInfo::Success);

      // Deterministic budget: an iteration cap per frame.
      FemSimulation capped(c.mesh, table(1e5, 0.45), opt);
      c.setup(capped);
      capped.cg().set_max_iterations(7);
      int total = 0, frames = 0;
      while (frames < 1000) {
        c.probe(capped, Vec3(0, 0, -0.2));  // re-set each frame, as a scene does: same values
        const FrameStats& st = capped.step();
        CHECK(st.resumed == (frames > 0));
        total += st.iterations;
        ++frames;
        if (st.info == SolveInfo::Success) break;
        CHECK(st.info == SolveInfo::NoConvergence);
      }
      CHECK(capped.last_stats().info == SolveInfo::Success);
      CHECK(total == one.iterations);  // the same iteration, split over frames
      CHECK(frames == (one.iterations + 6) / 7);
      CHECK((capped.displacement() - ref.displacement()).norm() <= 1e-12 * ref.displacement().norm());

      // Wall-clock budget: at least one iteration per frame, same sum, same answer.
      opt.cg.budget_ms = 1e-3;
      FemSimulation timed(c.mesh, table(1e5, 0.45), opt);
      c.setup(timed);
      c.probe(timed, Vec3(0, 0, -0.2));
      total = 0;
      for (frames = 0; frames < 5000; ++frames) {
        const FrameStats& st = timed.step();
        total += st.iterations;
        if (st.info == SolveInfo::Success) break;
        CHECK(st.budget_exhausted);
      }
      CHECK(timed.last_stats().info == SolveInfo::Success);
      CHECK(total == one.iterations);
      CHECK((timed.displacement() - ref.displacement()).norm() <= 1e-12 * ref.displacement().norm());
    }
  }
}

TEST_CASE("time the frame spent before the step (a cut) comes off the budget", "[fem][frames]") {
  for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
    ProbedCantilever c;
    FemSimulationOptions opt;
    opt.kind = kind;
    opt.cg.tolerance = 1e-9;
    opt.cg.preconditioner = Preconditioner::Jacobi;
    FemSimulation ref(c.mesh, table(1e5, 0.45), opt);
    c.setup(ref);
    c.probe(ref, Vec3(0, 0, -0.2));
    REQUIRE(ref.step().info == SolveInfo::Success);
    REQUIRE(ref.last_stats().iterations > 5);
    // Corotational: a frame relinearizes once; frames on the same load converge to equilibrium.
    for (int f = 0; f < 40; ++f) ref.step();

    // A budget far above the solve's cost: nothing spent, the frame converges.
    opt.cg.budget_ms = 1e6;
    FemSimulation sim(c.mesh, table(1e5, 0.45), opt);
    c.setup(sim);
    c.probe(sim, Vec3(0, 0, -0.2));
    CHECK(sim.step(0.0).info == SolveInfo::Success);
    CHECK(sim.last_stats().outside_ms == 0);

    // The same budget already spent by a cut: one iteration, the budget reported exhausted; the
    // frames after resume and reach the same answer.
    FemSimulation spent(c.mesh, table(1e5, 0.45), opt);
    c.setup(spent);
    c.probe(spent, Vec3(0, 0, -0.2));
    const FrameStats first = spent.step(2e6);
    CHECK(first.outside_ms == 2e6);
    CHECK(first.iterations == 1);
    CHECK(first.budget_exhausted);
    if (kind == FemKind::Corotational) {
      // The first refresh is whole (it measures the cost); a later frame with its budget spent
      // refreshes one packet of rotations, not all.
      CHECK(first.relinearized == 1);
      c.probe(spent, Vec3(0, 0, -0.21));
      CHECK(spent.step(2e6).relinearized < 0.5);
      c.probe(spent, Vec3(0, 0, -0.2));
    }
    int frames = 0;
    while ((spent.step().info != SolveInfo::Success || frames < 40) && frames < 200) ++frames;
    CHECK(spent.last_stats().info == SolveInfo::Success);
    CHECK((spent.displacement() - ref.displacement()).norm() <= 1e-6 * ref.displacement().norm());
  }
}

TEST_CASE("a change between budgeted frames restarts CG and still converges", "[fem][frames]") {
  ProbedCantilever c;
  FemSimulationOptions opt;
  opt.cg.tolerance = 1e-9;
  opt.cg.preconditioner = Preconditioner::Jacobi;  // capped at 5 iterations: needs many frames
  FemSimulation sim(c.mesh, table(1e5, 0.3), opt);
  c.setup(sim);
  sim.cg().set_max_iterations(5);
  c.probe(sim, Vec3(0, 0, -0.1));
  sim.step();
  c.probe(sim, Vec3(0, 0, -0.12));  // the probe moved: a restart, not a resume
  CHECK(!sim.step().resumed);
  CHECK(sim.step().resumed);
  int frames = 0;
  while (sim.step().info != SolveInfo::Success && frames < 2000) ++frames;
  CHECK(sim.last_stats().info == SolveInfo::Success);
  FemSimulation ref(c.mesh, table(1e5, 0.3), opt);
  c.setup(ref);
  c.probe(ref, Vec3(0, 0, -0.12));
  ref.step();
  CHECK((sim.displacement() - ref.displacement()).norm() <= 1e-7 * ref.displacement().norm());
}

TEST_CASE("predicting warm start: never a worse start than the last solution, fewer iterations on a steady probe",
          "[fem][frames]") {
  // Steady, then accelerating, then reversing: prediction is right, wrong, then very wrong.
  auto path = [](int f) {
    if (f < 12) return -0.01 * f;
    if (f < 20) return -0.12 - 0.002 * (f - 12) * (f - 12);
    return -0.248 + 0.03 * (f - 20);
  };
  ProbedCantilever c;
  auto run = [&](bool warm, bool predict, std::vector<FrameStats>& st) {
    FemSimulationOptions opt;
    opt.warm_start = warm;
    opt.predict = predict;
    opt.cg.tolerance = 1e-8;
    // Jacobi: enough iterations per frame for the counts to compare (bench_fem_precond
    // measures the default, Cholesky).
    opt.cg.preconditioner = Preconditioner::Jacobi;
    FemSimulation sim(c.mesh, table(1e5, 0.3), opt);
    c.setup(sim);
    int total = 0, steady = 0;
    for (int f = 0; f < 28; ++f) {
      c.probe(sim, Vec3(0, 0, path(f)));
      st.push_back(sim.step());
      REQUIRE(st.back().info == SolveInfo::Success);
      total += st.back().iterations;
      if (f >= 3 && f < 12) steady += st.back().iterations;
    }
    return std::pair<int, int>(total, steady);
  };
  std::vector<FrameStats> cold_st, last_st, pred_st;
  const auto [cold, cold_steady] = run(false, false, cold_st);
  const auto [last, last_steady] = run(true, false, last_st);
  const auto [pred, pred_steady] = run(true, true, pred_st);
  WARN("iterations over 28 frames: cold " << cold << ", last solution " << last << ", predicted " << pred
                                          << "; steady part: " << cold_steady << " / " << last_steady << " / "
                                          << pred_steady);
  for (std::size_t f = 0; f < pred_st.size(); ++f) {
    INFO("frame " << f);
    CHECK(pred_st[f].initial_relative_residual <= pred_st[f].guess_relative_residual * (1 + 1e-12));
    // Same problems, previous frames converged to 1e-8 in both runs.
    CHECK(pred_st[f].initial_relative_residual <= last_st[f].initial_relative_residual * (1 + 1e-4) + 1e-7);
  }
  CHECK(pred_steady < last_steady);
  CHECK(last < cold);
}

TEST_CASE("a frame right after a topology change starts from the last solution, not the extrapolation", "[fem][frames]") {
  // The history at new vertices is interpolated from their parents; extrapolating it through
  // a cut cost iterations on the organ (docs/solver.md). A frame after a change costs the
  // products of a run without prediction (no direction products) and starts where it does;
  // the next frames predict again.
  auto run = [](bool predict) {
    ProbedCantilever c;
    FemSimulationOptions opt;
    opt.cg.tolerance = 1e-8;
    opt.cg.preconditioner = Preconditioner::Jacobi;
    opt.predict = predict;
    FemSimulation sim(c.mesh, table(1e5, 0.3), opt);
    c.setup(sim);
    c.mesh.discard_change();
    std::mt19937 rng(11);
    std::vector<FrameStats> out;
    for (int f = 0; f < 12; ++f) {
      if (f == 6 || f == 9) {
        while (!random_edit(c.mesh, rng)) {
        }
        const TopologyChange change = c.mesh.take_change();
        REQUIRE_FALSE(change.empty());
        sim.apply(change);
      }
      c.probe(sim, Vec3(0, 0, -0.01 * f));
      out.push_back(sim.step());
      REQUIRE(out.back().info == SolveInfo::Success);
    }
    return out;
  };
  const std::vector<FrameStats> pred = run(true), last = run(false);
  for (int f = 3; f < 12; ++f) {  // from frame 3 the history has directions
    INFO("frame " << f);
    const FrameStats &p = pred[std::size_t(f)], &l = last[std::size_t(f)];
    if (f == 6 || f == 9) {
      CHECK(p.products - p.iterations == l.products - l.iterations);
      CHECK(p.initial_relative_residual == p.guess_relative_residual);
      if (f == 6) CHECK(p.guess_relative_residual == Approx(l.guess_relative_residual).epsilon(1e-6));  // same history so far
    } else {
      CHECK(p.products - p.iterations > l.products - l.iterations);  // the directions' products
    }
  }
}

TEST_CASE("warm-start directions: polynomial extrapolation up to order 4 is in their span, kept unknowns are 0",
          "[fem][frames][predict]") {
  // u(t) = a + b t + c t^2 + d t^3 + e t^4 per unknown: the order-4 Newton extrapolation
  // u1 + d1 + d2 + d3 + d4 from t = 0..4 gives u(5) exactly; fewer frames give fewer directions.
  const int n = 6;
  Eigen::MatrixXd coef = Eigen::MatrixXd::Random(n, 5);
  auto u = [&](double t) {
    Eigen::VectorXd x(n);
    for (int i = 0; i < n; ++i) x[i] = coef(i, 0) + t * (coef(i, 1) + t * (coef(i, 2) + t * (coef(i, 3) + t * coef(i, 4))));
    return x;
  };
  std::vector<std::uint8_t> free(n, 1);
  free[2] = 0;
  WarmStartPredictor p;
  std::vector<Eigen::VectorXd> d;
  CHECK(p.directions(free, d) == 0);
  for (int t = 0; t < 5; ++t) {
    p.record(u(t));
    CHECK(p.directions(free, d) == std::min(t, 4));
  }
  // One more frame: still four directions (the oldest frame dropped).
  Eigen::VectorXd pred = u(4);
  for (const Eigen::VectorXd& di : d) pred += di;
  const Eigen::VectorXd exact = u(5);
  for (int i = 0; i < n; ++i) {
    if (!free[std::size_t(i)]) {
      for (const Eigen::VectorXd& di : d) CHECK(di[i] == 0);
      continue;
    }
    CHECK(pred[i] == Approx(exact[i]).margin(1e-9 * std::max(1.0, std::abs(exact[i]))));
  }
  p.record(u(5));
  CHECK(p.directions(free, d) == 4);
  pred = u(5);
  for (const Eigen::VectorXd& di : d) pred += di;
  const Eigen::VectorXd next = u(6);
  for (int i = 0; i < n; ++i)
    if (free[std::size_t(i)]) CHECK(pred[i] == Approx(next[i]).margin(1e-9 * std::max(1.0, std::abs(next[i]))));
}
