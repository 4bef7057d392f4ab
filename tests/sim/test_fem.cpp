// FEM verification: patch test, uniaxial bar, cantilever against Timoshenko beam theory,
// matrix-free = assembled, CG = direct, corotational rigid-body invariance, dynamic mode,
// breakdown and under-constraint diagnostics, extremes of material and scale.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>
#include <sstream>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "sim/fem/assembled_stiffness.h"
#include "sim/fem/fem_model.h"
#include "sim/fem/fem_simulation.h"
#include "sim/springs/spring_model.h"
#include "tests/sim/fem_test_util.h"

using namespace incise;
using namespace incise::testing;

namespace {

Eigen::Matrix3d rotation(double angle, Vec3 axis) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

// Uniaxial stress sigma along x in a bar [0,L]x[0,W]x[0,W]: exact u = (s x/E, -nu s y/E, -nu s z/E).
// x = 0 face prescribed to the exact field, consistent traction on x = L: FEM must be exact.
struct BarResult {
  double error = 0;  // max nodal error / max displacement
  FrameStats stats;
};
BarResult uniaxial_bar(double scale, const MaterialTable& mats, double sigma, FemSimulationOptions opt,
                       std::array<int, 3> cells = {8, 3, 3}, std::function<double(const Vec3&)> young_at = {}) {
  const double len = 4 * scale, w = 1 * scale;
  TetMesh m = make_box(Vec3(len, w, w), cells);
  MaterialTable mt = mats;
  if (young_at) {  // two labels, interface at x = L/2 (a cell plane)
    for (TetId t : m.tets()) {
      Vec3 c = Vec3::Zero();
      for (VertexId v : m.tet_vertices(t)) c += m.rest(v) / 4;
      m.set_label(t, c.x() < len / 2 ? 1 : 2);
    }
  }
  FemSimulation sim(m, mt, opt);
  auto exact = [&](const Vec3& x) -> Vec3 {
    if (young_at) {  // nu = 0 in series: piecewise linear u_x
      const double e1 = mt.get(1).young, e2 = mt.get(2).young;
      const double ux = x.x() < len / 2 ? sigma * x.x() / e1 : sigma * (len / 2) / e1 + sigma * (x.x() - len / 2) / e2;
      return Vec3(ux, 0, 0);
    }
    const Material& mm = mt.fallback();
    return Vec3(sigma * x.x() / mm.young, -mm.poisson * sigma * x.y() / mm.young, -mm.poisson * sigma * x.z() / mm.young);
  };
  for (VertexId v : m.vertices())
    if (m.rest(v).x() < 1e-9 * scale) sim.prescribe(v, exact(m.rest(v)));
  add_face_traction(m, sim, 0, len, Vec3(sigma, 0, 0), 1e-9 * scale);
  BarResult r;
  r.stats = sim.step();
  double err = 0, ref = 0;
  for (VertexId v : m.vertices()) {
    err = std::max(err, (sim.displacement().segment<3>(3 * v.idx()) - exact(m.rest(v))).norm());
    ref = std::max(ref, exact(m.rest(v)).norm());
  }
  r.error = err / ref;
  return r;
}

}  // namespace

TEST_CASE("patch test: a linear field on the boundary is reproduced exactly inside", "[fem][verification]") {
  for (std::uint32_t seed : {1u, 2u}) {
    TetMesh m = make_box(Vec3(1, 2, 1.5), {4, 5, 4});
    jitter(m, 0.3, seed);
    const auto on_b = boundary_vertices(m);
    Eigen::Matrix3d a;
    a << 0.01, -0.02, 0.005, 0.003, -0.01, 0.02, -0.015, 0.007, 0.012;
    const Vec3 c(0.1, -0.2, 0.3);
    auto field = [&](const Vec3& x) -> Vec3 { return a * x + c; };

    for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
      // Interior rows of K u_linear vanish (the patch test proper).
      FemModel model(m, table(1e5, 0.3), kind);
      Eigen::VectorXd u = Eigen::VectorXd::Zero(model.rows()), y;
      for (VertexId v : m.vertices()) u.segment<3>(3 * v.idx()) = field(m.rest(v));
      model.multiply(u, y);
      const double scale = model.diagonal().maxCoeff() * max_abs(u);
      double interior = 0;
      for (VertexId v : m.vertices())
        if (!on_b[v.idx()]) interior = std::max(interior, y.segment<3>(3 * v.idx()).cwiseAbs().maxCoeff());
      CHECK(interior <= 1e-13 * scale);

      for (SolverMethod method : {SolverMethod::Direct, SolverMethod::Cg}) {
        FemSimulationOptions opt;
        opt.kind = kind;
        opt.method = method;
        opt.cg.tolerance = 1e-14;
        opt.nonlinear_iterations = 3;
        FemSimulation sim(m, table(1e5, 0.3), opt);
        for (VertexId v : m.vertices())
          if (on_b[v.idx()]) sim.prescribe(v, field(m.rest(v)));
        const FrameStats& st = sim.step();
        INFO("kind " << int(kind) << " method " << int(method) << ": " << st.message);
        CHECK(st.info == SolveInfo::Success);
        double err = 0;
        for (VertexId v : m.vertices()) err = std::max(err, (sim.displacement().segment<3>(3 * v.idx()) - field(m.rest(v))).norm());
        CHECK(err <= 1e-11 * max_abs(u));
      }
    }
  }
}

TEST_CASE("uniaxial bar is exact", "[fem][verification]") {
  for (SolverMethod method : {SolverMethod::Direct, SolverMethod::Cg}) {
    for (StiffnessBackend backend : {StiffnessBackend::MatrixFree, StiffnessBackend::Assembled}) {
      FemSimulationOptions opt;
      opt.method = method;
      opt.backend = backend;
      opt.cg.tolerance = 1e-13;
      const BarResult r = uniaxial_bar(1, table(2e6, 0.3), 1e3, opt);
      INFO(r.stats.message);
      CHECK(r.stats.info == SolveInfo::Success);
      CHECK(r.error < 1e-10);
    }
  }
}

TEST_CASE("cantilever tip deflection converges to Timoshenko beam theory", "[fem][verification][scale]") {
  // Beam L x h x h clamped at x = 0, shear load P (z) spread over the tip face.
  const double len = 8, h = 1, e = 1e6, nu = 0.3, p = -10;
  const double inertia = h * h * h * h / 12, area = h * h, g = e / (2 * (1 + nu));
  const double kappa = 10 * (1 + nu) / (12 + 11 * nu);  // rectangular section (Cowper)
  const double theory = p * len * len * len / (3 * e * inertia) + p * len / (kappa * g * area);
  std::ostringstream table_out;
  table_out << "cantilever L/h=" << len / h << ", Timoshenko tip deflection " << theory << "\n"
            << " cells        tets   tip_defl    rel_error\n";
  double prev_err = 1e300;
  std::vector<double> errs;
  for (int n : {1, 2, 3, 4, 6, 8}) {
    TetMesh m = make_box(Vec3(len, h, h), {int(len) * n, n, n});
    FemSimulationOptions opt;
    opt.method = SolverMethod::Direct;
    FemSimulation sim(m, table(e, nu), opt);
    for (VertexId v : m.vertices())
      if (m.rest(v).x() < 1e-9) sim.fix(v);
    add_face_traction(m, sim, 0, len, Vec3(0, 0, p / area), 1e-9);
    sim.step();
    double tip = 0;
    int count = 0;
    for (VertexId v : m.vertices())
      if (m.rest(v).x() > len - 1e-9) {
        tip += sim.displacement()[3 * v.idx() + 2];
        ++count;
      }
    tip /= count;
    const double err = std::abs(tip - theory) / std::abs(theory);
    table_out << " " << int(len) * n << "x" << n << "x" << n << "  " << m.num_tets() << "  " << tip << "  " << err << "\n";
    CHECK(err < prev_err);  // monotone convergence (linear tets approach from the stiff side)
    CHECK(std::abs(tip) < std::abs(theory) * 1.02);
    prev_err = err;
    errs.push_back(err);
  }
  // Observed order from the last three levels (h ratio 4:6:8) and the Richardson estimate of
  // the limit: the FEM converges to beam theory, not merely towards something.
  const double e4 = errs[3], e6 = errs[4], e8 = errs[5];
  // Order from levels 4->6, used to extrapolate 6->8 (an independent prediction).
  const double order = std::log(e4 / e6) / std::log(1.5);
  const double limit_err = std::abs(e8 - (e6 - e8) / (std::pow(8.0 / 6.0, order) - 1));
  table_out << "observed order " << order << " (6->8: " << std::log(e6 / e8) / std::log(8.0 / 6.0)
            << "), Richardson-extrapolated error of the limit " << limit_err << "\n";
  WARN(table_out.str());
  CHECK(prev_err < 0.08);
  CHECK(order > 1.0);
  CHECK(limit_err < 0.03);
}

TEST_CASE("matrix-free K*x equals the assembled matrix product", "[fem]") {
  std::mt19937 rng(4);
  std::normal_distribution<double> nd;
  for (int scale_exp : {-3, 0, 3}) {
    const double s = std::pow(10.0, scale_exp);
    TetMesh m = make_box(Vec3(1 * s, 2 * s, 1 * s), {5, 7, 4});
    jitter(m, 0.3, 9);
    MaterialTable mats = table(3e4, 0.4);
    Material stiff = mats.fallback();
    stiff.young = 3e8;
    mats.set(2, stiff);
    for (TetId t : m.tets())
      if (t.idx() % 3 == 0) m.set_label(t, 2);
    for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
      FemModel model(m, mats, kind);
      Eigen::VectorXd u(model.rows());
      for (Eigen::Index i = 0; i < u.size(); ++i) u[i] = 0.3 * s * nd(rng);
      model.update_rotations(u);  // large random rotations per tet
      AssembledStiffness as(model);
      for (int k = 0; k < 3; ++k) {
        Eigen::VectorXd x(model.rows()), y1, y2;
        for (Eigen::Index i = 0; i < x.size(); ++i) x[i] = nd(rng);
        model.multiply(x, y1);
        as.multiply(x, y2);
        CHECK((y1 - y2).norm() <= 1e-12 * y1.norm());
        CHECK((y1 - as.matrix() * x).norm() <= 1e-12 * y1.norm());
      }
      CHECK((model.diagonal() - as.diagonal()).norm() <= 1e-12 * model.diagonal().norm());
      // K is symmetric.
      const Eigen::SparseMatrix<double> kt = as.matrix().transpose();
      CHECK((as.matrix() - kt).norm() <= 1e-12 * as.matrix().norm());
    }
  }
}

TEST_CASE("CG equals the direct solution to tolerance, on both backends", "[fem]") {
  TetMesh m = make_box(Vec3(6, 1, 1), {18, 3, 3});
  jitter(m, 0.2, 3);
  auto run = [&](SolverMethod method, StiffnessBackend backend, Preconditioner pc) {
    FemSimulationOptions opt;
    opt.method = method;
    opt.backend = backend;
    opt.cg.tolerance = 1e-10;
    opt.cg.preconditioner = pc;
    opt.gravity = Vec3(0, 0, -9.81);
    FemSimulation sim(m, table(1e5, 0.35), opt);
    for (VertexId v : m.vertices())
      if (m.rest(v).x() < 1e-9) sim.fix(v);
    const FrameStats st = sim.step();
    INFO(st.message);
    CHECK(st.info == SolveInfo::Success);
    CHECK(st.relative_residual <= 1e-10);
    return std::pair<Eigen::VectorXd, int>(sim.displacement(), st.iterations);
  };
  const auto [ref, _] = run(SolverMethod::Direct, StiffnessBackend::MatrixFree, Preconditioner::Jacobi);
  const auto [mf, it_mf] = run(SolverMethod::Cg, StiffnessBackend::MatrixFree, Preconditioner::Jacobi);
  const auto [as, it_as] = run(SolverMethod::Cg, StiffnessBackend::Assembled, Preconditioner::Jacobi);
  const auto [np, it_np] = run(SolverMethod::Cg, StiffnessBackend::MatrixFree, Preconditioner::None);
  CHECK((mf - ref).norm() <= 1e-6 * ref.norm());
  CHECK((as - ref).norm() <= 1e-6 * ref.norm());
  CHECK((np - ref).norm() <= 1e-6 * ref.norm());
  CHECK(std::abs(it_mf - it_as) <= 2);  // same operator up to rounding
  CHECK(it_mf > 0);
  WARN("CG iterations: Jacobi " << it_mf << ", none " << it_np);
}

TEST_CASE("a rigid rotation gives zero force with corotational elements and not with linear", "[fem]") {
  TetMesh m = make_ellipsoid(Vec3(1, 0.7, 0.5), 3);
  jitter(m, 0.2, 8);
  for (double angle : {0.1, 1.0, 3.0}) {
    const Eigen::Matrix3d q = rotation(angle, Vec3(1, 2, 3));
    const Vec3 c(0.3, -1, 2);
    FemModel lin(m, table(1e6, 0.3), FemKind::Linear), cor(m, table(1e6, 0.3), FemKind::Corotational);
    Eigen::VectorXd u = Eigen::VectorXd::Zero(lin.rows()), f_lin, f_cor;
    for (VertexId v : m.vertices()) u.segment<3>(3 * v.idx()) = q * m.rest(v) + c - m.rest(v);
    lin.internal_forces(u, f_lin);
    cor.update_rotations(u);
    cor.internal_forces(u, f_cor);
    const double force_scale = 1e6 * 0.1 * 0.1;  // E * h^2 for unit strain
    INFO("angle " << angle << ": |f_lin|max " << max_abs(f_lin) << ", |f_cor|max " << max_abs(f_cor));
    CHECK(max_abs(f_cor) <= 1e-10 * force_scale);
    CHECK(max_abs(f_lin) > 1e-3 * angle * angle * force_scale);
    // Rotations recovered per tet.
    for (TetId t : m.tets()) CHECK((cor.rotation(t) - q).norm() < 1e-9);
  }
}

TEST_CASE("corotational agrees with linear for small loads and stays finite for inverted elements", "[fem]") {
  TetMesh m = make_box(Vec3(4, 1, 1), {8, 2, 2});
  auto tip = [&](FemKind kind, double load, int frames) {
    FemSimulationOptions opt;
    opt.kind = kind;
    opt.method = SolverMethod::Direct;
    FemSimulation sim(m, table(1e6, 0.3), opt);
    for (VertexId v : m.vertices())
      if (m.rest(v).x() < 1e-9) sim.fix(v);
    add_face_traction(m, sim, 0, 4, Vec3(0, 0, load), 1e-9);
    for (int i = 0; i < frames; ++i) sim.step();
    return sim.displacement();
  };
  const Eigen::VectorXd ul = tip(FemKind::Linear, -1, 1), uc = tip(FemKind::Corotational, -1, 10);
  CHECK((ul - uc).norm() <= 1e-3 * ul.norm());
  // Inverted elements: prescribe a collapse; the rotations and forces stay finite.
  FemModel cor(m, table(1e6, 0.3), FemKind::Corotational);
  Eigen::VectorXd u = Eigen::VectorXd::Zero(cor.rows()), f;
  for (VertexId v : m.vertices()) u.segment<3>(3 * v.idx()) = Vec3(-2 * m.rest(v).x(), 0, -m.rest(v).z() * 1.5);
  cor.update_rotations(u);
  cor.internal_forces(u, f);
  CHECK(f.allFinite());
  for (TetId t : m.tets()) CHECK(cor.rotation(t).determinant() == Approx(1).epsilon(1e-9));
}

TEST_CASE("dynamic backward Euler settles on the static solution and does not gain energy", "[fem][dynamic]") {
  TetMesh m = make_box(Vec3(3, 0.5, 0.5), {12, 2, 2});
  const double e = 1e7;  // first bending period ~1.1 s; damping 5/s settles it within 6 s
  FemSimulationOptions st_opt;
  st_opt.method = SolverMethod::Direct;
  st_opt.gravity = Vec3(0, 0, -9.81);
  FemSimulation stat(m, table(e, 0.3), st_opt);
  FemSimulationOptions dyn_opt = st_opt;
  dyn_opt.method = SolverMethod::Cg;
  dyn_opt.dynamic = true;
  dyn_opt.dt = 0.01;
  dyn_opt.damping = 5;
  dyn_opt.cg.tolerance = 1e-10;
  FemSimulation dyn(m, table(e, 0.3), dyn_opt);
  for (VertexId v : m.vertices())
    if (m.rest(v).x() < 1e-9) {
      stat.fix(v);
      dyn.fix(v);
    }
  stat.step();
  double prev_energy = 1e300;
  FemModel k(m, table(e, 0.3));
  for (int i = 0; i < 600; ++i) {
    const FrameStats& s = dyn.step();
    REQUIRE(s.info == SolveInfo::Success);
    REQUIRE(dyn.displacement().allFinite());
    if (i > 300) {  // after the initial drop the total energy decays (damped, dissipative scheme)
      Eigen::VectorXd ku;
      k.multiply(dyn.displacement(), ku);
      const Eigen::VectorXd& mass = k.lumped_mass();
      double grav = 0;
      for (Eigen::Index j = 2; j < mass.size(); j += 3) grav += mass[j] * 9.81 * dyn.displacement()[j];
      const double energy = 0.5 * dyn.displacement().dot(ku) + 0.5 * dyn.velocity().dot(mass.cwiseProduct(dyn.velocity())) + grav;
      CHECK(energy <= prev_energy + 1e-12 * std::abs(prev_energy));
      prev_energy = energy;
    }
  }
  CHECK((dyn.displacement() - stat.displacement()).norm() <= 1e-3 * stat.displacement().norm());

  // Without constraints the dynamic mode is still well posed (mass term): a free fall.
  FemSimulationOptions free_opt = dyn_opt;
  free_opt.damping = 0;
  FemSimulation fall(m, table(1e5, 0.3), free_opt);
  for (int i = 0; i < 10; ++i) REQUIRE(fall.step().info == SolveInfo::Success);
  // Backward Euler free fall: v_n = -g n dt exactly, u_n = -g dt^2 n(n+1)/2.
  const double expect = -9.81 * 0.01 * 0.01 * 10 * 11 / 2;
  for (Eigen::Index j = 2; j < fall.displacement().size(); j += 3) CHECK(fall.displacement()[j] == Approx(expect).epsilon(1e-8));
}

TEST_CASE("under-constrained static solves are refused with a message naming the part", "[fem][errors]") {
  TetMesh m = make_box(Vec3(2, 1, 1), {4, 2, 2});
  FemSimulation none(m, table(1e5, 0.3));
  none.set_gravity(Vec3(0, 0, -1));
  CHECK_THROWS_WITH(none.step(), Catch::Contains("under-constrained") && Catch::Contains("0 constrained"));

  FemSimulation line(m, table(1e5, 0.3));  // fixed nodes on one edge: free rotation about it
  for (VertexId v : m.vertices())
    if (m.rest(v).y() < 1e-9 && m.rest(v).z() < 1e-9) line.fix(v);
  CHECK_THROWS_WITH(line.step(), Catch::Contains("all on one line"));

  // Two parts, one fixed: the other is named.
  TetMesh cut = make_box(Vec3(2, 1, 1), {4, 2, 2});
  for (TetId t : cut.tets()) {
    Vec3 c = Vec3::Zero();
    for (VertexId v : cut.tet_vertices(t)) c += cut.rest(v) / 4;
    if (c.x() > 0.5 && c.x() < 1.0) cut.remove_tet(t);
  }
  cut.discard_change();
  FemSimulation two(cut, table(1e5, 0.3));
  for (VertexId v : cut.vertices())
    if (cut.rest(v).x() < 1e-9) two.fix(v);
  CHECK_THROWS_WITH(two.step(), Catch::Contains("1 of 2 connected parts"));
  for (VertexId v : cut.vertices())
    if (cut.rest(v).x() > 2 - 1e-9) two.fix(v);
  CHECK_NOTHROW(two.step());

  // The direct solver detects the singularity on its own too.
  FemModel model(m, table(1e5, 0.3));
  DirectSolver direct;
  std::vector<std::uint8_t> all_free(model.num_dofs(), 1);
  CHECK_THROWS_WITH(direct.compute(model.assemble(), all_free), Catch::Contains("singular"));
}

TEST_CASE("breakdowns are reported: NaN loads, indefinite operators, iteration cap, budget", "[fem][errors]") {
  TetMesh m = make_box(Vec3(4, 1, 1), {12, 3, 3});
  // Jacobi: the iteration cap and the budget below need a solve of many iterations.
  FemSimulationOptions opt;
  opt.cg.preconditioner = Preconditioner::Jacobi;
  FemSimulation sim(m, table(1e5, 0.3), opt);
  for (VertexId v : m.vertices())
    if (m.rest(v).x() < 1e-9) sim.fix(v);
  sim.set_force(VertexId(100), Vec3(std::nan(""), 0, 0));
  const FrameStats s1 = sim.step();
  CHECK(s1.info == SolveInfo::NumericalIssue);
  CHECK_THAT(s1.message, Catch::Contains("NaN"));
  sim.clear_forces();
  sim.reset_state();

  // Negative-definite operator (a material with E < 0 bypassing the checks is impossible, so
  // negate the model through a wrapper).
  struct Negated : LinearOperator {
    const FemModel& k;
    Eigen::VectorXd d;
    explicit Negated(const FemModel& m) : k(m), d(-m.diagonal()) {}
    Eigen::Index rows() const override { return k.rows(); }
    void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const override {
      k.multiply(x, y);
      y = -y;
    }
    const Eigen::VectorXd& diagonal() const override { return d; }
  } neg(sim.model());
  ConjugateGradient cg;
  cg.set_preconditioner(Preconditioner::None);
  cg.compute(neg, &sim.free_mask());
  Eigen::VectorXd b = Eigen::VectorXd::Ones(neg.rows());
  cg.solve(b);
  CHECK(cg.info() == SolveInfo::NotPositiveDefinite);
  CHECK_THAT(cg.stats().message, Catch::Contains("not positive definite"));

  // Iteration cap: reported, finite, not converged; warm start finishes over later frames.
  add_face_traction(m, sim, 0, 4, Vec3(0, 0, -10), 1e-9);
  sim.options().cg.max_iterations = 40;
  sim.cg().set_max_iterations(40);
  const FrameStats s2 = sim.step();
  CHECK(s2.info == SolveInfo::NoConvergence);
  CHECK(s2.iterations == 40);
  CHECK_THAT(s2.message, Catch::Contains("not converged"));
  CHECK(sim.displacement().allFinite());
  double prev = s2.relative_residual;
  int frames = 0;
  while (sim.step().info != SolveInfo::Success && frames < 3000) {
    CHECK(sim.last_stats().relative_residual < 10 * prev);  // no blow-up across restarts
    prev = sim.last_stats().relative_residual;
    ++frames;
  }
  CHECK(sim.last_stats().info == SolveInfo::Success);

  // Budget: a tiny budget stops early and says so.
  sim.reset_state();
  sim.cg().set_max_iterations(100000);
  sim.cg().set_budget_ms(1e-4);
  sim.options().cg.budget_ms = 1e-4;
  const FrameStats s3 = sim.step();
  CHECK(s3.budget_exhausted);
  CHECK(s3.info == SolveInfo::BudgetExhausted);
  CHECK(s3.iterations >= 1);
}

TEST_CASE("warm start: an unchanged load converges at once, a moving probe needs fewer iterations", "[fem]") {
  TetMesh m = make_box(Vec3(4, 1, 1), {16, 4, 4});
  auto run = [&](bool warm) {
    FemSimulationOptions opt;
    opt.warm_start = warm;
    opt.cg.tolerance = 1e-8;
    FemSimulation sim(m, table(1e5, 0.3), opt);
    std::vector<VertexId> probe;
    for (VertexId v : m.vertices()) {
      if (m.rest(v).x() < 1e-9) sim.fix(v);
      if (m.rest(v).x() > 4 - 1e-9) probe.push_back(v);
    }
    int total = 0;
    for (int f = 0; f < 10; ++f) {
      for (VertexId v : probe) sim.prescribe(v, Vec3(0, 0, -0.01 * f));
      total += sim.step().iterations;
      REQUIRE(sim.last_stats().info == SolveInfo::Success);
    }
    const int repeat = sim.step().iterations;  // same load again
    return std::pair<int, int>(total, repeat);
  };
  const auto [cold, cold_repeat] = run(false);
  const auto [warm, warm_repeat] = run(true);
  WARN("moving probe, 10 frames: cold " << cold << " iterations, warm " << warm);
  CHECK(warm < cold);
  CHECK(warm_repeat == 0);
  CHECK(cold_repeat > 0);
}

TEST_CASE("materials: Poisson's ratio 0.5 and above is refused by displacement-only models", "[fem][errors]") {
  Material m;
  m.poisson = 0.5;
  // A table may hold 0.5 (the mixed formulation solves it); a displacement-only model may not.
  const MaterialTable incompressible(m);
  const TetMesh box = make_box(Vec3(1, 1, 1), {1, 1, 1});
  CHECK_THROWS_WITH(FemModel(box, incompressible), Catch::Contains("0.5"));
  CHECK_THROWS_WITH(SpringModel(box, incompressible), Catch::Contains("0.5"));
  m.poisson = 0.51;
  CHECK_THROWS_WITH(MaterialTable(m), Catch::Contains("0.51"));
  m.poisson = 0.3;
  m.young = -1;
  CHECK_THROWS_AS(MaterialTable(m), InvalidArgument);
}

TEST_CASE("extremes: nu up to 0.4999, E from 1e1 to 1e9, 1e4 stiffness ratio, scale 1e-3..1e3", "[fem][extremes]") {
  std::ostringstream log;
  auto check = [&](const std::string& what, const BarResult& r, double tol) {
    log << what << ": iterations " << r.stats.iterations << ", residual " << r.stats.relative_residual << ", error "
        << r.error << (r.stats.info == SolveInfo::Success ? "" : "  [" + r.stats.message + "]") << "\n";
    INFO(what << ": " << r.stats.message);
    CHECK(std::isfinite(r.error));
    if (r.stats.info == SolveInfo::Success) CHECK(r.error < tol);
    else CHECK_FALSE(r.stats.message.empty());  // not converged: clearly reported
  };
  FemSimulationOptions opt;
  opt.cg.tolerance = 1e-10;
  opt.cg.max_iterations = 20000;
  for (double nu : {0.0, 0.3, 0.45, 0.49, 0.499, 0.4999}) {
    check("nu=" + std::to_string(nu), uniaxial_bar(1, table(1e6, nu), 1e3, opt), 1e-6);
    FemSimulationOptions d = opt;
    d.method = SolverMethod::Direct;
    const BarResult r = uniaxial_bar(1, table(1e6, nu), 1e3, d);
    CHECK(r.error < 1e-8);
  }
  for (double e : {1e1, 1e3, 1e5, 1e7, 1e9})
    check("E=" + std::to_string(e), uniaxial_bar(1, table(e, 0.3), 1e-3 * e, opt), 1e-6);
  for (double s : {1e-3, 1e3})
    for (double e : {1e1, 1e9})
      check("scale=" + std::to_string(s) + " E=" + std::to_string(e), uniaxial_bar(s, table(e, 0.3), 1e-3 * e, opt), 1e-6);
  for (double ratio : {1e4, 1e-4}) {
    MaterialTable two = table(1e5, 0.0);
    Material b = two.fallback();
    b.young = 1e5 * ratio;
    two.set(2, b);
    two.set(1, two.fallback());
    check("two labels ratio " + std::to_string(ratio),
          uniaxial_bar(1, two, 10, opt, {8, 3, 3}, [](const Vec3&) { return 0.0; }), 1e-6);
  }
  // Corotational at extremes too.
  FemSimulationOptions cor = opt;
  cor.kind = FemKind::Corotational;
  cor.nonlinear_iterations = 4;
  for (double s : {1e-3, 1e3}) {
    const BarResult r = uniaxial_bar(s, table(1e9, 0.45), 1e3, cor);
    check("corotational scale=" + std::to_string(s), r, 1e-4);
  }
  WARN(log.str());
}
