// Preconditioners: CG with each one equals the direct solution (static linear, corotational,
// dynamic); block-Jacobi and the asynchronous Cholesky follow topology changes, and after cuts
// every frame still converges while the stale factor preconditions.
#include <catch2/catch.hpp>

#include <chrono>
#include <random>
#include <thread>

#include <Eigen/Cholesky>
#include <tbb/global_control.h>

#include "mesh/generate.h"
#include "sim/fem/async_cholesky.h"
#include "sim/fem/fem_simulation.h"
#include "tests/sim/fem_test_util.h"

using namespace incise;
using namespace incise::testing;
using incise::testing::crack;

namespace {

const Preconditioner kAll[] = {Preconditioner::None, Preconditioner::Jacobi, Preconditioner::BlockJacobi,
                               Preconditioner::Cholesky, Preconditioner::Amg};

// A 1D Laplacian of n unknowns (SPD), for CG tests that need no mesh.
struct Laplacian : LinearOperator {
  Eigen::VectorXd d;
  explicit Laplacian(Eigen::Index n) : d(Eigen::VectorXd::Constant(n, 2.0)) {}
  Eigen::Index rows() const override { return d.size(); }
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const override {
    y = 2 * x;
    y.tail(x.size() - 1) -= x.head(x.size() - 1);
    y.head(x.size() - 1) -= x.tail(x.size() - 1);
  }
  const Eigen::VectorXd& diagonal() const override { return d; }
};

// Jacobi that counts its applications, optionally sleeping in each, with a cheaper() one.
struct CountingJacobi : CgPreconditioner {
  const LinearOperator* op = nullptr;
  mutable int applications = 0;
  int sleep_ms = 0;
  CgPreconditioner* cheap = nullptr;
  void setup(const LinearOperator& o, const std::vector<std::uint8_t>*) override { op = &o; }
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const override {
    ++applications;
    if (sleep_ms) std::this_thread::sleep_for(std::chrono::milliseconds(sleep_ms));
    z = r.cwiseQuotient(op->diagonal());
  }
  CgPreconditioner* cheaper() override { return cheap; }
};

}  // namespace

TEST_CASE("CG with every preconditioner equals the direct solution", "[fem][preconditioner]") {
  TetMesh m = make_box(Vec3(4, 1, 1), {16, 4, 4});
  jitter(m, 0.25, 7);
  for (bool dynamic : {false, true})
    for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
      auto run = [&](SolverMethod method, Preconditioner pc, bool background) {
        FemSimulationOptions opt;
        opt.kind = kind;
        opt.method = method;
        opt.dynamic = dynamic;
        opt.cg.tolerance = 1e-10;
        opt.cg.preconditioner = pc;
        opt.cholesky.background = background;
        opt.gravity = Vec3(0, 0, -9.81);
        FemSimulation sim(m, table(1e5, 0.45), opt);
        fix_ends(m, sim);
        sim.set_force(VertexId(40), Vec3(0, 30, 5));
        int iterations = 0;
        for (int f = 0; f < 3; ++f) {
          const FrameStats& st = sim.step();
          INFO(st.message);
          REQUIRE(st.info == SolveInfo::Success);
          iterations += st.iterations;
        }
        return std::pair<Eigen::VectorXd, int>(sim.displacement(), iterations);
      };
      const auto [ref, _] = run(SolverMethod::Direct, Preconditioner::Jacobi, true);
      for (Preconditioner pc : kAll)
        for (bool background : {false, true}) {
          if (background && pc != Preconditioner::Cholesky) continue;
          INFO("dynamic " << dynamic << ", kind " << int(kind) << ", " << to_string(pc) << ", background " << background);
          const auto [u, it] = run(SolverMethod::Cg, pc, background);
          CHECK((u - ref).norm() <= 1e-7 * ref.norm());
          if (pc == Preconditioner::Cholesky && kind == FemKind::Linear) CHECK(it <= 3 * 3);  // exact factor
        }
    }
}

TEST_CASE("block-Jacobi blocks follow topology changes", "[fem][preconditioner][local]") {
  TetMesh m = make_box(Vec3(2, 1, 1), {6, 3, 3});
  jitter(m, 0.2, 3);
  m.discard_change();
  FemModel model(m, table(3e4, 0.4));
  std::mt19937 rng(5);
  for (int e = 0; e < 300; ++e) {
    random_edit(m, rng, true);
    if (e % 10 == 9) model.apply(m.take_change());
  }
  model.apply(m.take_change());
  FemModel fresh(m, table(3e4, 0.4));
  for (VertexId v : m.vertices())
    CHECK((model.diagonal_blocks()[v.idx()] - fresh.diagonal_blocks()[v.idx()]).norm() <=
          1e-12 * fresh.diagonal_blocks()[v.idx()].norm());
}

TEST_CASE("after cuts every frame converges while the stale factor preconditions", "[fem][preconditioner][cut]") {
  for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
    TetMesh m = make_box(Vec3(4, 1, 1), {16, 4, 4});
    m.discard_change();
    FemSimulationOptions opt;
    opt.kind = kind;
    opt.cg.tolerance = 1e-8;
    opt.cg.preconditioner = Preconditioner::Cholesky;
    opt.cholesky.settle_frames = 0;  // the stale factor preconditions through the cuts
    FemSimulation sim(m, table(1e5, 0.45), opt);
    fix_ends(m, sim);
    std::vector<VertexId> top;
    for (VertexId v : m.vertices())
      if (m.rest(v).z() > 1 - 1e-9) top.push_back(v);
    for (VertexId v : top) sim.set_force(v, Vec3(0, 0, -2));
    REQUIRE(sim.step().info == SolveInfo::Success);
    // Deepen the cut by one cell per frame, feeding each change to the simulation; frames
    // never wait for the refactorization.
    for (int depth = 1; depth <= 3; ++depth) {
      crack(m, 0, 2.0, 2, 1.0 - 0.25 * depth - 1e-3);
      const TopologyChange change = m.take_change();
      REQUIRE(!change.added_vertices.empty());
      sim.apply(change);
      const FrameStats& st = sim.step();
      INFO("depth " << depth << ": " << st.message);
      CHECK(st.info == SolveInfo::Success);
      UNSCOPED_INFO("cut " << depth << ": " << st.iterations << " iterations, factorizing "
                           << sim.cholesky()->factorizing() << ", factors adopted "
                           << sim.cholesky()->factorizations());
    }
    m.validate();
    // The answer on the cut mesh is the direct one (same loads: on the original top vertices).
    check_equals_direct(m, opt, top, sim);
    CHECK(sim.cholesky()->factorizations() >= 1);
    WARN("kind " << int(kind) << ": after the cuts, factors adopted " << sim.cholesky()->factorizations());
  }
}

TEST_CASE("settle policy: block-Jacobi while the topology changes, a factor of the settled mesh after", "[fem][preconditioner][cut]") {
  TetMesh m = make_box(Vec3(4, 1, 1), {16, 4, 4});
  m.discard_change();
  FemSimulationOptions opt;
  opt.kind = FemKind::Corotational;
  opt.cg.tolerance = 1e-8;
  opt.cg.preconditioner = Preconditioner::Cholesky;
  opt.cholesky.background = false;  // deterministic: a started factorization lands in the same frame
  opt.cholesky.settle_frames = 2;
  FemSimulation sim(m, table(1e5, 0.45), opt);
  fix_ends(m, sim);
  std::vector<VertexId> top;
  for (VertexId v : m.vertices())
    if (m.rest(v).z() > 1 - 1e-9) top.push_back(v);
  for (VertexId v : top) sim.set_force(v, Vec3(0, 0, -2));
  REQUIRE(sim.step().info == SolveInfo::Success);
  REQUIRE(sim.cholesky()->factorizations() == 1);
  CHECK_FALSE(sim.cholesky()->settling());
  // A blade deepening every frame: no factorization starts, block-Jacobi alone preconditions.
  for (int depth = 1; depth <= 3; ++depth) {
    crack(m, 0, 2.0, 2, 1.0 - 0.25 * depth - 1e-3);
    sim.apply(m.take_change());
    CHECK(sim.step().info == SolveInfo::Success);
    CHECK(sim.cholesky()->settling());
    CHECK(sim.cholesky()->factorizations() == 1);
  }
  // Quiet frames: after settle_frames without a change, a factor of the cut mesh is made and used.
  int frames = 0;
  while (sim.cholesky()->settling() && frames < 5) {
    CHECK(sim.step().info == SolveInfo::Success);
    ++frames;
  }
  CHECK_FALSE(sim.cholesky()->settling());
  CHECK(frames == 2);
  CHECK(sim.cholesky()->factorizations() == 2);
  // The answer is the direct one on the cut mesh.
  check_equals_direct(m, opt, top, sim);
}

TEST_CASE("the first factor, waited for, is made on the frame's thread, later ones in the background", "[fem][preconditioner]") {
  // A factor the frame waits for, made on the lowest-priority thread, left the frame blocked on a
  // thread that hardly ran while other processes kept the cores busy: only factors the frames
  // do not wait for go there.
  for (bool wait_for_first : {true, false}) {
    INFO("wait_for_first " << wait_for_first);
    TetMesh m = make_box(Vec3(4, 1, 1), {12, 3, 3});
    m.discard_change();
    FemSimulationOptions opt;
    opt.cg.tolerance = 1e-8;
    opt.cg.preconditioner = Preconditioner::Cholesky;
    opt.cholesky.wait_for_first = wait_for_first;
    opt.cholesky.settle_frames = 0;
    FemSimulation sim(m, table(1e5, 0.3), opt);
    fix_ends(m, sim);
    for (VertexId v : m.vertices())
      if (m.rest(v).z() > 1 - 1e-9) sim.set_force(v, Vec3(0, 0, -2));
    REQUIRE(sim.step().info == SolveInfo::Success);
    if (wait_for_first) {
      CHECK(sim.cholesky()->factorizations() == 1);
      CHECK(sim.cholesky()->background_factorizations() == 0);
    } else {
      CHECK(sim.cholesky()->background_factorizations() == 1);
    }
    if (!wait_for_first) continue;  // its first job may still run: when the next starts is timing
    // A change: the next factor is not waited for (the old one preconditions meanwhile).
    crack(m, 0, 2.0, 2, 0.5);
    sim.apply(m.take_change());
    REQUIRE(sim.step().info == SolveInfo::Success);
    CHECK(sim.cholesky()->background_factorizations() == 1);
  }
}

TEST_CASE("a mesh above the factorization limit runs on the multigrid (block-Jacobi without it)",
          "[fem][preconditioner]") {
  for (bool amg : {true, false}) {
  INFO("settle_with_amg " << amg);
  TetMesh m = make_box(Vec3(4, 1, 1), {12, 3, 3});
  FemSimulationOptions opt;
  opt.cg.tolerance = 1e-10;
  opt.cg.preconditioner = Preconditioner::Cholesky;
  opt.cholesky.max_unknowns = 10;
  opt.cholesky.settle_with_amg = amg;
  opt.gravity = Vec3(0, 0, -9.81);
  FemSimulation sim(m, table(1e5, 0.3), opt);
  fix_ends(m, sim);
  FemSimulationOptions dopt = opt;
  dopt.method = SolverMethod::Direct;
  FemSimulation direct(m, table(1e5, 0.3), dopt);
  fix_ends(m, direct);
  direct.step();
  for (int f = 0; f < 3; ++f) REQUIRE(sim.step().info == SolveInfo::Success);
  CHECK(!sim.cholesky()->has_factor());
  CHECK(!sim.cholesky()->factorizing());
  CHECK(sim.cholesky()->uses_multigrid() == amg);
  CHECK((sim.amg() != nullptr) == amg);
  CHECK((sim.displacement() - direct.displacement()).norm() <= 1e-7 * direct.displacement().norm());
  }
}

TEST_CASE("corotational: the stale factor rotated is symmetric, and CG still equals the direct solution",
          "[fem][preconditioner][rotated]") {
  // The far end turned rigidly by up to 60 degrees: the factor of the first frame (no rotation)
  // is stale throughout, so the rotation change is large.
  TetMesh m = make_box(Vec3(4, 1, 1), {16, 4, 4});
  jitter(m, 0.25, 11);
  const int frames = 6;
  auto run = [&](SolverMethod method, bool rotate, std::unique_ptr<FemSimulation>& sim) {
    FemSimulationOptions opt;
    opt.kind = FemKind::Corotational;
    opt.method = method;
    opt.cg.tolerance = 1e-10;
    opt.cg.preconditioner = Preconditioner::Cholesky;
    opt.cholesky.background = false;
    opt.cholesky.refactor_iterations = 1000000;  // never refreshed: stale from frame 2 on
    opt.cholesky.rotate = rotate;
    sim = std::make_unique<FemSimulation>(m, table(1e5, 0.4), opt);
    std::vector<VertexId> end;
    for (VertexId v : m.vertices()) {
      if (m.rest(v).x() < 1e-9) sim->fix(v);
      if (m.rest(v).x() > 4 - 1e-9) end.push_back(v);
    }
    const Vec3 centre(4, 0.5, 0.5);
    for (int f = 1; f <= frames; ++f) {
      const double theta = (M_PI / 3) * f / frames, radius = 4 / theta;
      const Eigen::Matrix3d r = Eigen::AngleAxisd(-theta, Vec3::UnitY()).toRotationMatrix();
      const Vec3 tip(radius * std::sin(theta), 0.5, 0.5 + radius * (1 - std::cos(theta)));
      for (VertexId v : end) sim->prescribe(v, tip + r * (m.rest(v) - centre) - m.rest(v));
      const FrameStats& st = sim->step();
      INFO("frame " << f << ": " << st.message);
      REQUIRE(st.info == SolveInfo::Success);
    }
  };
  std::unique_ptr<FemSimulation> rotated, plain, direct;
  run(SolverMethod::Cg, true, rotated);
  run(SolverMethod::Cg, false, plain);
  run(SolverMethod::Direct, true, direct);
  REQUIRE(rotated->cholesky() != nullptr);
  REQUIRE(rotated->cholesky()->factorizations() == 1);

  const double ref = direct->displacement().norm();
  CHECK((rotated->displacement() - direct->displacement()).norm() <= 1e-6 * ref);
  CHECK((plain->displacement() - direct->displacement()).norm() <= 1e-6 * ref);

  // M^-1 as CG used it in the last frame: random residuals on the free unknowns.
  const auto& free = rotated->free_mask();
  std::mt19937 rng(5);
  auto random_residual = [&] { return random_free_residual(free, rng); };
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::VectorXd r1 = random_residual(), r2 = random_residual();
    Eigen::VectorXd z1, z2, p1;
    rotated->cholesky()->apply(r1, z1);
    rotated->cholesky()->apply(r2, z2);
    const double a = r1.dot(z2), b = r2.dot(z1);
    CHECK(std::abs(a - b) <= 1e-10 * std::max(std::abs(a), std::sqrt(r1.dot(z1) * r2.dot(z2))));
    CHECK(r1.dot(z1) > 0);
    // The rotation is in use: the unrotated stale factor gives a clearly different M^-1.
    plain->cholesky()->apply(r1, p1);
    CHECK((z1 - p1).norm() > 1e-2 * z1.norm());
  }
}

TEST_CASE("CG applies the preconditioner once per iteration, not once more after converging", "[cg][preconditioner]") {
  // A 1D Laplacian (SPD), Jacobi applied through a counting wrapper.
  Laplacian a(30);
  CountingJacobi pc;
  ConjugateGradient cg;
  cg.set_tolerance(1e-10);
  cg.set_preconditioner(&pc);
  cg.compute(a);
  const Eigen::VectorXd x = cg.solve(Eigen::VectorXd::Ones(30));
  REQUIRE(cg.info() == SolveInfo::Success);
  Eigen::VectorXd ax;
  a.multiply(x, ax);
  CHECK((ax - Eigen::VectorXd::Ones(30)).norm() <= 1e-9 * std::sqrt(30.0));
  // One application for the start, one per iteration that continues: the converged last
  // residual needs none (it cost a whole Cholesky solve per frame).
  CHECK(pc.applications == cg.iterations());
}

TEST_CASE("CG's iterates do not depend on the thread count, and kept unknowns keep their values", "[cg]") {
  // Long enough for the iteration's vector passes to split over threads (their partial sums
  // are per fixed block, added in block order). A shifted 1D Laplacian 3x_i - x_{i-1} - x_{i+1}
  // (SPD, well conditioned), every seventh unknown kept at a prescribed value.
  struct Shifted : Laplacian {
    explicit Shifted(Eigen::Index n) : Laplacian(n) { d.setConstant(3.0); }
    void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const override {
      Laplacian::multiply(x, y);
      y += x;
    }
  };
  const Eigen::Index n = 100003;
  Shifted a(n);
  std::vector<std::uint8_t> free(std::size_t(n), 1);
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::VectorXd b(n), start(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    b[i] = u(rng);
    start[i] = i % 7 == 0 ? u(rng) : 0.0;
    if (i % 7 == 0) free[std::size_t(i)] = 0;
  }
  auto run = [&](int threads, SolveStats& stats) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
    ConjugateGradient cg;
    cg.set_tolerance(1e-12);
    cg.set_preconditioner(Preconditioner::Jacobi);
    cg.compute(a, &free);
    Eigen::VectorXd x = start;
    cg.solve_with_guess(b, x);
    stats = cg.stats();
    return x;
  };
  SolveStats s1, s2;
  const Eigen::VectorXd x1 = run(1, s1), x2 = run(2, s2);
  REQUIRE(s1.info == SolveInfo::Success);
  CHECK(s1.iterations == s2.iterations);
  CHECK(s1.relative_residual == s2.relative_residual);
  CHECK((x1.array() == x2.array()).all());  // bit for bit
  // The answer: kept unknowns at their values, and A x = b on the free rows.
  Eigen::VectorXd ax;
  a.multiply(x1, ax);
  double worst = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!free[std::size_t(i)]) CHECK(x1[i] == start[i]);
    else worst = std::max(worst, std::abs(ax[i] - b[i]));
  }
  CHECK(worst < 1e-9);
}

TEST_CASE("a budget that cannot afford the preconditioner's application uses its cheaper one", "[cg][preconditioner][budget]") {
  // A 1D Laplacian; the "expensive" preconditioner is Jacobi that sleeps 20 ms per
  // application, its cheaper one plain Jacobi. With a 2 ms budget, once the cost is measured,
  // fresh solves start on the cheaper one, resumes keep it, and the run still converges.
  Laplacian a(200);
  CountingJacobi slow, fast;
  slow.sleep_ms = 20;
  slow.cheap = &fast;
  ConjugateGradient cg;
  cg.set_tolerance(1e-8);
  cg.set_preconditioner(&slow);
  cg.compute(a);
  const Eigen::VectorXd b = Eigen::VectorXd::Ones(200);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(200);
  // No budget: the preconditioner is used (and its cost measured).
  cg.set_max_iterations(2);
  cg.solve_with_guess(b, x);
  CHECK_FALSE(cg.stats().cheaper_preconditioner);
  CHECK(slow.applications > 0);
  CHECK(fast.applications == 0);
  // A fresh budgeted solve: 20 ms does not fit 2 ms, so the cheaper one runs; resumes keep it.
  cg.set_max_iterations(10000);
  cg.set_budget_ms(2);
  cg.invalidate();
  const int slow_before = slow.applications;
  int frames = 0;
  x.setZero();
  do {
    cg.solve_with_guess(b, x);
    CHECK(cg.stats().cheaper_preconditioner);
    CHECK(cg.iterations() >= 1);  // every budgeted solve progresses
    CHECK((frames == 0 || cg.stats().resumed));
  } while (cg.info() == SolveInfo::BudgetExhausted && ++frames < 100000);
  REQUIRE(cg.info() == SolveInfo::Success);
  CHECK(slow.applications == slow_before);
  CHECK(fast.applications > 0);
  Eigen::VectorXd ax;
  a.multiply(x, ax);
  CHECK((ax - b).norm() <= 1e-7 * b.norm());
  // A budget that affords it gets the preconditioner back.
  cg.set_budget_ms(1000);
  x.setZero();
  cg.solve_with_guess(b, x);
  CHECK_FALSE(cg.stats().cheaper_preconditioner);
  CHECK(slow.applications > slow_before);
}

TEST_CASE("Cholesky: a vertex touched by several edits gets its stale-row correction once", "[cholesky][preconditioner]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {3, 3, 3});
  m.discard_change();
  const MaterialTable mats(Material{1e4, 0.3, 1});
  FemModel model(m, mats);
  std::vector<std::uint8_t> free(model.rows(), 1);
  for (VertexId v : m.vertices())
    if (m.rest(v).x() == 0)
      for (int c = 0; c < 3; ++c) free[3 * v.idx() + std::size_t(c)] = 0;
  auto z_after = [&](int touches) {
    AsyncCholeskyOptions o;
    o.background = false;
    AsyncCholesky pc(model, o);
    pc.setup(model, &free);
    pc.frame(free, 0, 1, 0);
    REQUIRE(pc.has_factor());
    TopologyChange ch;  // an edit that changed vertex 13's rows (its incident tets)
    ch.touched_vertices.push_back(VertexId(13));
    for (int k = 0; k < touches; ++k) pc.apply(ch);
    Eigen::VectorXd r = Eigen::VectorXd::LinSpaced(model.rows(), 1.0, 2.0), z;
    for (Eigen::Index i = 0; i < r.size(); ++i)
      if (!free[std::size_t(i)]) r[i] = 0;
    pc.apply(r, z);
    return z;
  };
  const Eigen::VectorXd once = z_after(1), thrice = z_after(3);
  CHECK((once - thrice).norm() <= 1e-14 * once.norm());
}

namespace {
// A block-diagonal operator: only what block-Jacobi reads.
struct Blocks : LinearOperator {
  std::vector<Eigen::Matrix3d> blocks;
  Eigen::VectorXd diag;
  Eigen::Index rows() const override { return Eigen::Index(3 * blocks.size()); }
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const override {
    y.resize(rows());
    for (std::size_t v = 0; v < blocks.size(); ++v) y.segment<3>(3 * Eigen::Index(v)) = blocks[v] * x.segment<3>(3 * Eigen::Index(v));
  }
  const Eigen::VectorXd& diagonal() const override { return diag; }
  const std::vector<Eigen::Matrix3d>& diagonal_blocks() const override { return blocks; }
};
}  // namespace

TEST_CASE("block-Jacobi inverts SPD blocks exactly, falls back to the diagonal otherwise, on either path", "[fem][preconditioner]") {
  // Below and above the size where the setup runs in parallel.
  for (std::size_t n : {50u, 9000u}) {
    std::mt19937 rng{unsigned(n)};
    std::uniform_real_distribution<double> u(-1, 1);
    Blocks op;
    op.blocks.resize(n);
    op.diag.resize(Eigen::Index(3 * n));
    for (std::size_t v = 0; v < n; ++v) {
      Eigen::Matrix3d g;
      for (int i = 0; i < 9; ++i) g(i / 3, i % 3) = u(rng);
      Eigen::Matrix3d a = g * g.transpose() + 0.05 * Eigen::Matrix3d::Identity();
      if (v % 7 == 3) a(2, 2) = -a(2, 2) - 1;  // indefinite
      if (v % 11 == 5) a *= 1e9;               // large entries
      op.blocks[v] = a;
      op.diag.segment<3>(3 * Eigen::Index(v)) = a.diagonal();
    }
    std::vector<std::uint8_t> free(3 * n, 1);
    free[3 * 10 + 1] = 0;  // one kept unknown: that vertex gets the diagonal fallback
    BlockJacobi bj;
    bj.setup(op, &free);
    Eigen::VectorXd r = Eigen::VectorXd::Random(Eigen::Index(3 * n)), z;
    bj.apply(r, z);
    for (std::size_t v = 0; v < n; ++v) {
      INFO("n " << n << ", vertex " << v);
      const auto rv = r.segment<3>(3 * Eigen::Index(v));
      Eigen::Vector3d expect;
      if (v % 7 == 3 || v == 10) {
        for (int c = 0; c < 3; ++c) {
          const double d = op.blocks[v](c, c);
          expect[c] = free[3 * v + std::size_t(c)] ? (d > 0 ? rv[c] / d : rv[c]) : 0.0;
        }
      } else {
        expect = op.blocks[v].llt().solve(rv);
      }
      CHECK((z.segment<3>(3 * Eigen::Index(v)) - expect).norm() <= 1e-9 * expect.norm());
    }
  }
}
