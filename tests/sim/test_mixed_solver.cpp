// Mixed displacement-pressure solver (sim/fem/mixed_solver.h): Lame's cylinder from nu = 0.3 to 0.5,
// MINRES = direct (also through budgeted, resumed calls), incompressibility, the patch test,
// and local updates after mesh edits equal a solver built from scratch.
#include <catch2/catch.hpp>

#include <random>

#include "mesh/generate.h"
#include "sim/fem/mixed_solver.h"
#include "testing/elasticity_cases.h"
#include "testing/mesh_edits.h"

using namespace incise;
using namespace incise::testing;

namespace {

MixedOptions direct_options() {
  MixedOptions o;
  o.direct = true;
  return o;
}

MixedOptions tolerance(double t) {
  MixedOptions o;
  o.tolerance = t;
  return o;
}

}  // namespace

TEST_CASE("mixed: Lame cylinder radial displacement within 3% up to nu = 0.5, converging", "[fem][mixed]") {
  for (double nu : {0.3, 0.49, 0.4999, 0.5}) {
    const LameResult coarse = run_lame(3, 6, 1, nu, direct_options());
    const LameResult fine = run_lame(8, 16, 2, nu, direct_options());
    INFO("nu " << nu << ": coarse " << coarse.error << " (max " << coarse.max_error << "), fine " << fine.error
               << " (max " << fine.max_error << ")");
    CHECK(coarse.stats.converged);
    CHECK(fine.error <= 0.03);
    CHECK(fine.max_error <= 0.03);
    CHECK(fine.error < coarse.error);
  }
}

TEST_CASE("mixed: MINRES equals the direct solve, also through budgeted resumed calls", "[fem][mixed]") {
  for (FemKind kind : {FemKind::Linear, FemKind::Corotational})
    for (double nu : {0.45, 0.5}) {
      const double a = 1, b = 2, h = 0.5;
      TetMesh m = make_quarter_tube(a, b, h, 4, 8, 2);
      jitter(m, 0.1, 3);
      Material mat{1e4, nu, 1000};
      MixedMaterials mats(mat);
      mat.young = 5e4;
      mats.set(2, mat);
      for (TetId t : m.tets())
        if (t.idx() % 3 == 0) m.set_label(t, 2);
      MixedOptions it_opt;
      it_opt.tolerance = 1e-10;
      MixedSolver direct(m, mats, kind, direct_options()), iterative(m, mats, kind, it_opt);
      MixedProblem pb(direct.num_dofs());
      for (VertexId v : m.vertices()) {
        const Vec3 x = m.rest(v);
        if (x.z() < 1e-9) pb.keep(v, 2);  // rollers, one prescribed
        if (x.y() < 1e-9) pb.keep(v, 1, x.z() > h - 1e-9 ? 1e-3 : 0.0);
        if (x.x() < 1e-9) pb.keep(v, 0);
        if (x.z() > h - 1e-9) pb.f[3 * Eigen::Index(v.idx())] = 0.5;
      }
      Eigen::VectorXd rot = 0.05 * Eigen::VectorXd::Random(pb.u.size());
      direct.update_rotations(rot);
      iterative.update_rotations(rot);
      Eigen::VectorXd ud = pb.u, ui = pb.u;
      const MixedStats sd = direct.solve(pb.f, pb.free, ud);
      const MixedStats si = iterative.solve(pb.f, pb.free, ui);
      INFO("kind " << int(kind) << " nu " << nu << ": " << si.iterations << " iterations, residual "
                   << si.relative_residual << ", direct residual " << sd.relative_residual);
      CHECK(sd.converged);
      CHECK(si.converged);
      CHECK(sd.relative_residual <= 1e-9);
      CHECK((ui - ud).norm() <= 1e-7 * ud.norm());
      CHECK((iterative.pressure() - direct.pressure()).norm() <= 1e-6 * direct.pressure().norm());

      // The asynchronous Cholesky factor of K_mu as the displacement preconditioner (rollers:
      // most vertices here fall back to block-Jacobi; the clamped test below is its fast case).
      MixedOptions chol_opt = it_opt;
      chol_opt.preconditioner = MixedPreconditioner::Cholesky;
      MixedSolver chol(m, mats, kind, chol_opt);
      chol.update_rotations(rot);
      Eigen::VectorXd uh = pb.u;
      const MixedStats sh = chol.solve(pb.f, pb.free, uh);
      INFO("Cholesky: " << sh.iterations << " iterations");
      CHECK(sh.converged);
      CHECK((uh - ud).norm() <= 1e-7 * ud.norm());

      // The same solve in slices of 7 iterations, each call resuming from the last.
      MixedOptions sliced = it_opt;
      sliced.max_iterations = 7;
      MixedSolver chunks(m, mats, kind, sliced);
      chunks.update_rotations(rot);
      Eigen::VectorXd uc = pb.u;
      int calls = 0, total = 0, resumed = 0;
      MixedStats sc;
      do {
        sc = chunks.solve(pb.f, pb.free, uc);
        ++calls;
        total += sc.iterations;
        resumed += sc.resumed;
      } while (!sc.converged && calls < 1000);
      CHECK(sc.converged);
      CHECK(resumed == calls - 1);
      CHECK(std::abs(total - si.iterations) <= 2);
      CHECK((uc - ud).norm() <= 1e-7 * ud.norm());

      // And by wall-clock budget: a tiny budget per call still adds up to the answer.
      MixedOptions budget = it_opt;
      budget.budget_ms = 0.2;
      MixedSolver timed(m, mats, kind, budget);
      timed.update_rotations(rot);
      Eigen::VectorXd ut = pb.u;
      int tcalls = 0;
      MixedStats stt;
      do {
        stt = timed.solve(pb.f, pb.free, ut);
        ++tcalls;
      } while (!stt.converged && tcalls < 5000);
      CHECK(stt.converged);
      CHECK((ut - ud).norm() <= 1e-7 * ud.norm());
    }
}

TEST_CASE("mixed: incompressible block under compression keeps its volume", "[fem][mixed]") {
  const double e = 1e4, s = 100;
  for (double nu : {0.3, 0.5}) {
    TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
    jitter(m, 0.15, 11);
    MixedSolver solver(m, MixedMaterials(Material{e, nu, 1000}), FemKind::Linear, tolerance(1e-10));
    MixedProblem pb(solver.num_dofs());
    for (VertexId v : m.vertices())
      if (m.rest(v).z() < 1e-9)
        for (int d = 0; d < 3; ++d) pb.keep(v, d);  // clamped: a non-uniform field
    add_traction(m, pb, [](const Vec3& x) { return x.z() > 1 - 1e-9; },
                 [&](const Vec3&, const Vec3&) -> Vec3 { return Vec3(0, 0, -s); });
    const MixedStats st = solver.solve(pb.f, pb.free, pb.u);
    CHECK(st.converged);
    const double dv = solver.volume_change(pb.u), scale = s / e;  // strain scale x unit volume
    INFO("nu " << nu << ": volume change " << dv << " (strain scale " << scale << "), top displacement "
               << pb.u.minCoeff());
    if (nu == 0.5) CHECK(std::abs(dv) <= 1e-6 * scale);
    else CHECK(dv < -0.1 * scale);
    CHECK(pb.u.minCoeff() < -0.3 * scale);  // it does compress
  }
}

TEST_CASE("mixed: patch test, an affine field with constant pressure is exact", "[fem][mixed]") {
  const double e = 2e3;
  for (FemKind kind : {FemKind::Linear, FemKind::Corotational})
    for (double nu : {0.3, 0.5}) {
      TetMesh m = make_box(Vec3(2, 1, 1), {5, 3, 3});
      jitter(m, 0.2, 5);
      const Material mat{e, nu, 1000};
      Eigen::Matrix3d grad;
      grad << 1e-3, 2e-3, -1e-3, 0.5e-3, -3e-3, 1e-3, 0, 1e-3, 2e-3;  // trace 0: admissible at 0.5
      const double p0 = nu == 0.5 ? 3.7 : -mat.lambda() * grad.trace();
      const Eigen::Matrix3d sigma = mat.mu() * (grad + grad.transpose()) - p0 * Eigen::Matrix3d::Identity();
      auto exact = [&](const Vec3& x) -> Vec3 { return grad * x + Vec3(1e-3, -2e-3, 0.5e-3); };
      MixedSolver solver(m, MixedMaterials(mat), kind, tolerance(1e-12));
      MixedProblem pb(solver.num_dofs());
      for (VertexId v : m.vertices())
        if (m.rest(v).x() < 1e-9)
          for (int d = 0; d < 3; ++d) pb.keep(v, d, exact(m.rest(v))[d]);
      add_traction(m, pb, [](const Vec3&) { return true; },
                   [&](const Vec3&, const Vec3& n) -> Vec3 { return sigma * n; });
      // Tractions on x = 0 are reactions: the prescribed unknowns ignore their loads.
      const MixedStats st = solver.solve(pb.f, pb.free, pb.u);
      double err = 0, ref = 0, perr = 0;
      for (VertexId v : m.vertices()) {
        err = std::max(err, (pb.u.segment<3>(3 * Eigen::Index(v.idx())) - exact(m.rest(v))).norm());
        ref = std::max(ref, exact(m.rest(v)).norm());
        perr = std::max(perr, std::abs(solver.pressure()[v.idx()] - p0));
      }
      INFO("kind " << int(kind) << " nu " << nu << ": displacement error " << err / ref << ", pressure error "
                   << perr << " of " << p0 << ", " << st.iterations << " iterations");
      CHECK(st.converged);
      CHECK(err <= 1e-8 * ref);
      CHECK(perr <= 1e-7 * std::max(1.0, std::abs(p0)));
    }
}

TEST_CASE("mixed: after local edits the solver equals one built from scratch", "[fem][mixed][local]") {
  for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
    TetMesh m = make_box(Vec3(2, 1, 1), {6, 3, 3});
    jitter(m, 0.2, 8);
    for (TetId t : m.tets())
      if (t.idx() % 4 == 0) m.set_label(t, 2);
    m.discard_change();
    MixedMaterials mats(Material{1e4, 0.5, 1000});
    mats.set(2, Material{4e4, 0.45, 1000});
    MixedSolver local(m, mats, kind, direct_options());
    std::mt19937 rng(31);
    Eigen::VectorXd p = Eigen::VectorXd::Random(Eigen::Index(local.vertex_slots()));
    local.set_pressure(p);
    // A MINRES solver whose multigrid is built before the edits and patched through them.
    MixedSolver iter(m, mats, kind, tolerance(1e-10));
    {
      MixedProblem pb(iter.num_dofs());
      for (VertexId v : m.vertices())
        if (m.rest(v).x() < 1e-9)
          for (int d = 0; d < 3; ++d) pb.keep(v, d);
      pb.f.setConstant(0.1);
      REQUIRE(iter.solve(pb.f, pb.free, pb.u).converged);
    }
    for (int batch = 0; batch < 40; ++batch) {
      for (int k = 0; k < 3; ++k) random_edit(m, rng, false);
      const TopologyChange change = m.take_change();
      local.apply(change);
      iter.apply(change);
    }
    m.validate();
    MixedSolver scratch(m, mats, kind, direct_options());
    Eigen::VectorXd rot = Eigen::VectorXd::Zero(Eigen::Index(local.num_dofs()));
    for (VertexId v : m.vertices()) rot.segment<3>(3 * Eigen::Index(v.idx())) = 0.05 * Vec3::Random();
    Eigen::VectorXd rot_s = rot.head(Eigen::Index(scratch.num_dofs()));
    local.update_rotations(rot);
    iter.update_rotations(rot);
    scratch.update_rotations(rot_s);

    // Same operator on the mesh's slots.
    const Eigen::Index nv = Eigen::Index(m.vertex_capacity());
    auto full = [&](const MixedSolver& s, const Eigen::VectorXd& u, const Eigen::VectorXd& q) {
      Eigen::VectorXd x = Eigen::VectorXd::Zero(Eigen::Index(s.num_dofs() + s.vertex_slots()));
      x.head(3 * nv) = u.head(3 * nv);
      x.segment(Eigen::Index(s.num_dofs()), nv) = q.head(nv);
      return x;
    };
    Eigen::VectorXd u = Eigen::VectorXd::Random(3 * nv), q = Eigen::VectorXd::Random(nv), yl, ys;
    local.multiply(full(local, u, q), yl);
    scratch.multiply(full(scratch, u, q), ys);
    const Eigen::Index ol = Eigen::Index(local.num_dofs()), os = Eigen::Index(scratch.num_dofs());
    CHECK((yl.head(3 * nv) - ys.head(3 * nv)).norm() <= 1e-12 * ys.head(3 * nv).norm());
    CHECK((yl.segment(ol, nv) - ys.segment(os, nv)).norm() <= 1e-12 * ys.segment(os, nv).norm());
    CHECK((local.pressure_diagonal().head(nv) - scratch.pressure_diagonal().head(nv)).norm() <=
          1e-12 * scratch.pressure_diagonal().norm());

    // Same solution: clamped at x = 0, pulled on x = 2.
    auto solve = [&](MixedSolver& s) {
      MixedProblem pb(s.num_dofs());
      for (VertexId v : m.vertices())
        if (m.rest(v).x() < 1e-9)
          for (int d = 0; d < 3; ++d) pb.keep(v, d);
      add_traction(m, pb, [](const Vec3& x) { return x.x() > 2 - 1e-9; },
                   [](const Vec3&, const Vec3&) -> Vec3 { return Vec3(50, 0, 20); });
      CHECK(s.solve(pb.f, pb.free, pb.u).converged);
      return Eigen::VectorXd(pb.u.head(3 * nv));
    };
    const Eigen::VectorXd sl = solve(local), ss = solve(scratch), si = solve(iter);
    CHECK((sl - ss).norm() <= 1e-9 * ss.norm());
    CHECK((si - ss).norm() <= 1e-7 * ss.norm());
  }
}

TEST_CASE("mixed: backward Euler steps (a M + c K) match direct and settle to the static solution", "[fem][mixed][dynamic]") {
  TetMesh m = make_box(Vec3(2, 1, 1), {6, 3, 3});
  jitter(m, 0.15, 4);
  const MixedMaterials mats(Material{1e4, 0.5, 1000});
  MixedSolver stat(m, mats, FemKind::Linear, direct_options());
  MixedProblem pb(stat.num_dofs());
  for (VertexId v : m.vertices())
    if (m.rest(v).x() < 1e-9)
      for (int d = 0; d < 3; ++d) pb.keep(v, d);
  add_traction(m, pb, [](const Vec3& x) { return x.x() > 2 - 1e-9; },
               [](const Vec3&, const Vec3&) -> Vec3 { return Vec3(0, 0, -200); });
  Eigen::VectorXd us = pb.u;
  REQUIRE(stat.solve(pb.f, pb.free, us).converged);

  const double dt = 0.2, damping = 1;
  MixedSolver dyn(m, mats, FemKind::Linear, tolerance(1e-10)), ref(m, mats, FemKind::Linear, direct_options());
  const Eigen::Index nu = Eigen::Index(dyn.num_dofs()), np = Eigen::Index(dyn.vertex_slots());
  Eigen::VectorXd u = pb.u, v = Eigen::VectorXd::Zero(nu), p = Eigen::VectorXd::Zero(np);
  const Eigen::VectorXd b0 = dyn.right_hand_side(pb.f);
  const Eigen::VectorXd& mass = dyn.deviatoric_model().lumped_mass();
  int iterations = 0;
  for (int step = 0; step < 150; ++step) {
    Eigen::VectorXd x0(nu + np), y;
    x0 << u, Eigen::VectorXd::Zero(np);
    dyn.multiply_static(x0, y);  // [K u; -B u]
    Eigen::VectorXd b(nu + np);
    b.head(nu) = mass.cwiseProduct(v) + dt * (b0.head(nu) - y.head(nu));
    b.tail(np) = dt * (b0.tail(np) - y.tail(np));
    dyn.set_system(1 + dt * damping, dt * dt);
    ref.set_system(1 + dt * damping, dt * dt);
    Eigen::VectorXd x(nu + np);
    x << v, p / dt;
    for (Eigen::Index i = 0; i < nu; ++i)
      if (!pb.free[std::size_t(i)]) x[i] = 0;  // fixed: zero velocity
    Eigen::VectorXd xr = x;
    const MixedStats st = dyn.solve_system(b, pb.free, x);
    iterations += st.iterations;
    REQUIRE(st.converged);
    if (step < 3) {
      REQUIRE(ref.solve_system(b, pb.free, xr).converged);
      CHECK((x - xr).head(nu).norm() <= 1e-7 * xr.head(nu).norm());
    }
    v = x.head(nu);
    p = dt * x.tail(np);
    u += dt * v;
  }
  INFO("150 steps, " << iterations << " MINRES iterations; static " << us.norm() << ", dynamic " << u.norm());
  CHECK((u - us).norm() <= 1e-3 * us.norm());
  CHECK((p - stat.pressure()).norm() <= 1e-2 * stat.pressure().norm());
  CHECK_THROWS(dyn.solve(pb.f, pb.free, u));  // solve() is the static solve only
}

TEST_CASE("mixed: corotational rigid rotation is stress-free, pressure and all", "[fem][mixed]") {
  TetMesh m = make_box(Vec3(2, 1, 1), {4, 2, 2});
  jitter(m, 0.15, 2);
  MixedSolver solver(m, MixedMaterials(Material{1e4, 0.5, 1000}), FemKind::Corotational);
  const Eigen::Matrix3d r = Eigen::AngleAxisd(0.9, Vec3(1, 2, -0.5).normalized()).toRotationMatrix();
  const Eigen::Index nu = Eigen::Index(solver.num_dofs()), np = Eigen::Index(solver.vertex_slots());
  Eigen::VectorXd x = Eigen::VectorXd::Zero(nu + np);
  for (VertexId v : m.vertices()) x.segment<3>(3 * Eigen::Index(v.idx())) = (r - Eigen::Matrix3d::Identity()) * m.rest(v);
  solver.update_rotations(x.head(nu));
  // [u; 0] with the rigid u satisfies A x = b(0): no force on u, no volume change on p.
  Eigen::VectorXd y;
  solver.multiply(x, y);
  const Eigen::VectorXd b = solver.right_hand_side(Eigen::VectorXd::Zero(nu));
  CHECK((y - b).head(nu).norm() <= 1e-9 * b.head(nu).norm());
  CHECK((y - b).tail(np).norm() <= 1e-9 * b.tail(np).norm());
  CHECK(std::abs(solver.volume_change(x.head(nu))) <= 1e-12 * m.total_volume());
}

TEST_CASE("mixed: the Cholesky displacement preconditioner on a clamped beam", "[fem][mixed]") {
  for (double nu : {0.3, 0.5}) {
    MixedOptions chol;
    chol.preconditioner = MixedPreconditioner::Cholesky;
    const CantileverResult c = run_cantilever(2, nu, chol), a = run_cantilever(2, nu), d = run_cantilever(2, nu, direct_options());
    INFO("nu " << nu << ": Cholesky " << c.stats.iterations << " iterations, multigrid " << a.stats.iterations);
    CHECK(c.stats.converged);
    CHECK(c.stats.iterations < a.stats.iterations);
    CHECK(std::abs(c.tip - d.tip) <= 1e-5 * std::abs(d.tip));
  }
}

TEST_CASE("mixed: corotational static iterations converge on a large deflection", "[fem][mixed]") {
  // Beam 4 x 0.5 x 0.5 clamped at x = 0, a tip load that bends it by a third of its length in
  // the linear model: re-linearizing about the last solution converges, and the corotational
  // tip swings back in x (the beam keeps its length) where the linear one only moves in z.
  TetMesh m = make_box(Vec3(4, 0.5, 0.5), {16, 2, 2});
  const MixedMaterials mats(Material{1e5, 0.5, 1000});
  MixedProblem pb(3 * m.vertex_capacity());
  for (VertexId v : m.vertices())
    if (m.rest(v).x() < 1e-9)
      for (int d = 0; d < 3; ++d) pb.keep(v, d);
  add_traction(m, pb, [](const Vec3& x) { return x.x() > 4 - 1e-9; },
               [](const Vec3&, const Vec3&) -> Vec3 { return Vec3(0, 0, -240); });
  auto tip = [&](const Eigen::VectorXd& u) {
    Vec3 s = Vec3::Zero();
    int n = 0;
    for (VertexId v : m.vertices())
      if (m.rest(v).x() > 4 - 1e-9) {
        s += u.segment<3>(3 * Eigen::Index(v.idx()));
        ++n;
      }
    return Vec3(s / n);
  };
  MixedSolver linear(m, mats, FemKind::Linear, direct_options()), corot(m, mats, FemKind::Corotational, direct_options());
  Eigen::VectorXd ul = pb.u, uc = pb.u;
  REQUIRE(linear.solve(pb.f, pb.free, ul).converged);
  double change = 0;
  for (int it = 0; it < 30; ++it) {
    const Eigen::VectorXd before = uc;
    corot.update_rotations(uc);
    REQUIRE(corot.solve(pb.f, pb.free, uc).converged);
    change = (uc - before).norm() / uc.norm();
  }
  const Vec3 tl = tip(ul), tc = tip(uc);
  INFO("linear tip " << tl.transpose() << ", corotational tip " << tc.transpose() << ", last change " << change);
  CHECK(tl.z() < -1.2);
  CHECK(std::abs(tl.x()) < 0.05 * std::abs(tl.z()));
  CHECK(change < 1e-6);
  CHECK(tc.x() < -0.1 * std::abs(tc.z()));  // swung back
  CHECK(std::abs(tc.z()) < std::abs(tl.z()));
  CHECK(std::abs(corot.volume_change(uc)) < 1e-6 * m.total_volume());
}
