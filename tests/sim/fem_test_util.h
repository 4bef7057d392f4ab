#pragma once
// Helpers shared by the FEM tests: loads on box faces, fixed ends, a run checked against the
// direct solution (random edits and jitter come from
// testing/mesh_edits.h).
#include <catch2/catch.hpp>

#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include "mesh/generate.h"
#include "mesh/tet_mesh.h"
#include "sim/fem/fem_simulation.h"
#include "testing/mesh_edits.h"

namespace incise::testing {

using incise::testing::boundary_vertices;
using incise::testing::jitter;
using incise::testing::random_edit;

// A random residual on the free unknowns, zero on kept ones (for checking M^-1 as CG uses it).
inline Eigen::VectorXd random_free_residual(const std::vector<std::uint8_t>& free, std::mt19937& rng) {
  std::normal_distribution<double> g;
  Eigen::VectorXd r(Eigen::Index(free.size()));
  for (Eigen::Index i = 0; i < r.size(); ++i) r[i] = free[std::size_t(i)] ? g(rng) : 0.0;
  return r;
}
using incise::testing::random_tet;

// One material for every label (E, nu, density).
inline MaterialTable table(double e, double nu, double rho = 1000) { return MaterialTable(Material{e, nu, rho}); }

// Consistent nodal forces of a uniform traction on the boundary faces lying in the plane
// x[axis] == value: each triangle gives traction * area / 3 to each of its corners.
inline void add_face_traction(const TetMesh& m, FemSimulation& sim, int axis, double value, const Vec3& traction,
                              double tol) {
  for (const auto& f : m.boundary_faces()) {
    bool in = true;
    for (VertexId v : f.vertices) in = in && std::abs(m.rest(v)[axis] - value) <= tol;
    if (!in) continue;
    const Vec3 a = m.rest(f.vertices[0]), b = m.rest(f.vertices[1]), c = m.rest(f.vertices[2]);
    const double area = 0.5 * (b - a).cross(c - a).norm();
    for (VertexId v : f.vertices) sim.add_force(v, traction * area / 3);
  }
}

// Both x ends (x = 0 and x = 4) of a 4-long box fixed.
inline void fix_ends(const TetMesh& m, FemSimulation& sim) {
  for (VertexId v : m.vertices())
    if (m.rest(v).x() < 1e-9 || m.rest(v).x() > 4 - 1e-9) sim.fix(v);
}

// After 8 more frames, `sim` (ends fixed, -2 z on `top`) equals the direct solution on m.
inline void check_equals_direct(const TetMesh& m, const FemSimulationOptions& opt, const std::vector<VertexId>& top,
                         FemSimulation& sim) {
  FemSimulationOptions dopt = opt;
  dopt.method = SolverMethod::Direct;
  FemSimulation direct(m, table(1e5, 0.45), dopt);
  fix_ends(m, direct);
  for (VertexId v : top) direct.set_force(v, Vec3(0, 0, -2));
  for (int f = 0; f < 8; ++f) {
    CHECK(sim.step().info == SolveInfo::Success);
    direct.step();
  }
  CHECK((sim.displacement() - direct.displacement()).norm() <= 1e-6 * direct.displacement().norm());
}

// The patch test of a formulation on a jittered box: an affine field prescribed on the
// boundary is reproduced inside (to 1e-9, unless `solve` is false), and its internal force
// vanishes at interior vertices. `per_tet` gets the model and the field for the formulation's
// own per-tet check (its stress or pressure) with the field's gradient.
inline void check_affine_patch(Formulation f, FemKind kind, double nu, bool solve,
                               const std::function<void(FemModel&, const Eigen::VectorXd&, const Eigen::Matrix3d&)>& per_tet) {
  TetMesh m = make_box(Vec3(2, 1, 1.5), {6, 3, 4});
  jitter(m, 0.25, 11);
  const auto boundary = boundary_vertices(m);
  Eigen::Matrix3d a;
  a << 0.01, 0.02, -0.01, 0.005, -0.03, 0.02, 0.0, 0.01, 0.015;
  const Vec3 shift(0.1, -0.2, 0.05);
  auto exact = [&](const Vec3& x) -> Vec3 { return a * x + shift; };
  FemSimulationOptions opt;
  opt.kind = kind;
  opt.formulation = f;
  opt.method = SolverMethod::Direct;
  opt.nonlinear_iterations = 6;
  FemSimulation sim(m, table(1e5, nu), opt);
  for (VertexId v : m.vertices())
    if (boundary[v.idx()]) sim.prescribe(v, exact(m.rest(v)));
  if (solve) {
    for (int k = 0; k < (kind == FemKind::Linear ? 1 : 3); ++k) REQUIRE(sim.step().info == SolveInfo::Success);
    double err = 0, ref = 0;
    for (VertexId v : m.vertices()) {
      err = std::max(err, (sim.displacement().segment<3>(3 * v.idx()) - exact(m.rest(v))).norm());
      ref = std::max(ref, exact(m.rest(v)).norm());
    }
    CHECK(err <= 1e-9 * ref);
  }
  FemModel& model = sim.model();
  Eigen::VectorXd u = Eigen::VectorXd::Zero(model.rows()), force;
  for (VertexId v : m.vertices()) u.segment<3>(3 * v.idx()) = exact(m.rest(v));
  model.update_rotations(u);
  model.internal_forces(u, force);
  double interior = 0, all = 0;
  for (VertexId v : m.vertices()) {
    all = std::max(all, force.segment<3>(3 * v.idx()).norm());
    if (!boundary[v.idx()]) interior = std::max(interior, force.segment<3>(3 * v.idx()).norm());
  }
  CHECK(interior <= 1e-9 * all);
  if (per_tet) per_tet(model, u, a);
}

inline double max_abs(const Eigen::VectorXd& v) { return v.size() ? v.cwiseAbs().maxCoeff() : 0.0; }

// Shared by the nodal-averaged and edge-smoothed tests (their own namespace: other FEM tests
// have helpers of these names).
namespace smoothed {
// The jittered 2 x 1 x 1 box (6 x 3 x 3 cells) with every third tet of label 2 (two_materials'
// hard one): the formulations' consistency checks against their assembled matrices.
inline TetMesh two_label_box() {
  TetMesh m = make_box(Vec3(2, 1, 1), {6, 3, 3});
  jitter(m, 0.25, 5);
  for (TetId t : m.tets())
    if (t.idx() % 3 == 0) m.set_label(t, 2);
  return m;
}

inline MaterialTable two_materials() {
  Material soft{2e4, 0.49, 900};
  Material hard{5e7, 0.2, 1900};
  MaterialTable t(soft);
  t.set(2, hard);
  return t;
}

inline Eigen::VectorXd random_vector(Eigen::Index n, std::mt19937& rng, double scale = 1) {
  std::normal_distribution<double> nd;
  Eigen::VectorXd x(n);
  for (Eigen::Index i = 0; i < n; ++i) x[i] = scale * nd(rng);
  return x;
}

// Relative difference of K x, diagonal, diagonal blocks and mass of two models on the mesh's
// vertex range, and (corotational) of b_R.
// Work of one FemModel::apply, averaged over 1000 random edits of an n^3 unit box of two
// materials (the locality tests: it must not grow with n).
struct WorkPerUpdate {
  double tets = 0, vertices = 0, blocks = 0, edges = 0;
};
inline WorkPerUpdate work_per_local_update(Formulation f, int n) {
  TetMesh m = make_box(Vec3(1, 1, 1), {n, n, n});
  m.discard_change();
  FemModel model(m, two_materials(), FemKind::Linear, f);
  model.reset_work();
  std::mt19937 rng(3);
  for (int i = 0; i < 1000; ++i) {
    random_edit(m, rng, true);
    model.apply(m.take_change());
  }
  const FemWork& w = model.work();
  const double u = double(w.updates);
  return {double(w.tets_recomputed) / u, double(w.vertices_updated) / u, double(w.blocks_updated) / u,
          double(w.edges_updated) / u};
}

inline double model_difference(const FemModel& a, const FemModel& b, const TetMesh& m, std::mt19937& rng) {
  const Eigen::Index n = Eigen::Index(3 * m.vertex_capacity());
  Eigen::VectorXd xa = Eigen::VectorXd::Zero(a.rows()), xb = Eigen::VectorXd::Zero(b.rows()), ya, yb;
  xa.head(n) = xb.head(n) = random_vector(n, rng);
  a.multiply(xa, ya);
  b.multiply(xb, yb);
  double d = (ya.head(n) - yb.head(n)).norm() / yb.head(n).norm();
  d = std::max(d, (a.diagonal().head(n) - b.diagonal().head(n)).norm() / b.diagonal().head(n).norm());
  d = std::max(d, (a.lumped_mass().head(n) - b.lumped_mass().head(n)).norm() / b.lumped_mass().head(n).norm());
  double blocks = 0, scale = 0;
  for (std::size_t v = 0; v < m.vertex_capacity(); ++v) {
    blocks += (a.diagonal_blocks()[v] - b.diagonal_blocks()[v]).squaredNorm();
    scale += b.diagonal_blocks()[v].squaredNorm();
  }
  d = std::max(d, std::sqrt(blocks / scale));
  if (a.kind() == FemKind::Corotational) {
    Eigen::VectorXd ra = Eigen::VectorXd::Zero(a.rows()), rb = Eigen::VectorXd::Zero(b.rows());
    a.add_rotation_rhs(ra);
    b.add_rotation_rhs(rb);
    d = std::max(d, (ra.head(n) - rb.head(n)).norm() / std::max(rb.head(n).norm(), 1e-300));
  }
  if (a.rows() > n) d = std::max(d, ya.tail(a.rows() - n).norm() + a.diagonal().tail(a.rows() - n).norm());
  return d;
}

// Cantilever L x h x h (L = 10 h), clamped at x = 0, a total shear load P (z) spread over the
// tip face; returns the mean tip deflection and Timoshenko's (Cowper's shear coefficient).
struct Cantilever {
  double fem = 0, theory = 0;
  double error() const { return fem / theory - 1; }  // negative: too stiff
};
// Solved by CG with the exact (CHOLMOD) Cholesky preconditioner to 1e-12: the direct solver's
// SimplicialLDLT takes ~25 s on the nodal-averaged 80x8x8 (2-ring pattern), CG ~2.5 s, and CG
// equals the direct solve (test above).
inline Cantilever cantilever(int nx, double nu, Formulation f) {
  const double len = 10, h = 1, e = 1e6, p = -1;
  const double inertia = h * h * h * h / 12, area = h * h, g = e / (2 * (1 + nu));
  const double shear = 10 * (1 + nu) / (12 + 11 * nu);
  Cantilever c;
  c.theory = p * len * len * len / (3 * e * inertia) + p * len / (shear * g * area);
  TetMesh m = make_box(Vec3(len, h, h), {nx, nx / 10, nx / 10});
  FemSimulationOptions opt;
  opt.formulation = f;
  opt.cg.tolerance = 1e-12;
  opt.cg.preconditioner = Preconditioner::Cholesky;
  opt.cholesky.background = false;
  opt.warm_start = false;
  FemSimulation sim(m, table(e, nu), opt);
  for (VertexId v : m.vertices())
    if (m.rest(v).x() < 1e-9) sim.fix(v);
  add_face_traction(m, sim, 0, len, Vec3(0, 0, p / area), 1e-9);
  REQUIRE(sim.step().info == SolveInfo::Success);
  int count = 0;
  for (VertexId v : m.vertices())
    if (m.rest(v).x() > len - 1e-9) {
      c.fem += sim.displacement()[3 * v.idx() + 2];
      ++count;
    }
  c.fem /= count;
  return c;
}



// The tests nodal-averaged and edge-smoothed tets share, per formulation.

// CG with every preconditioner, and the assembled backend, equals the direct solution (static and
// dynamic frames, linear and corotational); the exact Cholesky factor takes one iteration a
// frame. `pointwise_dynamic`: also Jacobi and block-Jacobi on the dynamic frames. `nx`: cells
// along the 4 x 1 x 1 box (nx / 4 across).
inline void check_cg_equals_direct(Formulation f, bool pointwise_dynamic, int nx = 16) {
  TetMesh m = make_box(Vec3(4, 1, 1), {nx, nx / 4, nx / 4});
  jitter(m, 0.25, 7);
  const Preconditioner all[] = {Preconditioner::Jacobi, Preconditioner::BlockJacobi, Preconditioner::Cholesky,
                                Preconditioner::Amg};
  for (bool dynamic : {false, true})
    for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
      auto run = [&](SolverMethod method, Preconditioner pc, StiffnessBackend backend = StiffnessBackend::MatrixFree) {
        FemSimulationOptions opt;
        opt.kind = kind;
        opt.formulation = f;
        opt.method = method;
        opt.backend = backend;
        opt.dynamic = dynamic;
        opt.cg.tolerance = 1e-11;
        opt.cg.max_iterations = 20000;
        opt.cg.preconditioner = pc;
        opt.cholesky.background = false;
        opt.gravity = Vec3(0, 0, -9.81);
        FemSimulation sim(m, table(1e5, 0.49), opt);
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
      const auto [ref, _] = run(SolverMethod::Direct, Preconditioner::Jacobi);
      for (Preconditioner pc : all) {
        // Dynamic frames (mass on the diagonal) converge fast with any preconditioner: the
        // point-wise ones may be left to the static frames (an expensive product instrumented).
        if (dynamic && !pointwise_dynamic && (pc == Preconditioner::Jacobi || pc == Preconditioner::BlockJacobi)) continue;
        const auto [u, it] = run(SolverMethod::Cg, pc);
        INFO("dynamic " << dynamic << ", kind " << int(kind) << ", " << to_string(pc) << ": " << it << " iterations");
        CHECK((u - ref).norm() <= 1e-7 * ref.norm());
        if (pc == Preconditioner::Cholesky && kind == FemKind::Linear) CHECK(it <= 3 * 3);  // the exact factor
      }
      const auto [ua, ita] = run(SolverMethod::Cg, Preconditioner::BlockJacobi, StiffnessBackend::Assembled);
      INFO("assembled backend: " << ita << " iterations");
      CHECK((ua - ref).norm() <= 1e-7 * ref.norm());
    }
}

// Through a crack deepened over three frames, CG with the stale factor and with the patched
// multigrid equals the direct solution.
inline void check_cuts_equal_direct(Formulation f) {
  for (Preconditioner pc : {Preconditioner::Cholesky, Preconditioner::Amg})
    for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
      INFO(to_string(pc) << ", kind " << int(kind));
      TetMesh m = make_box(Vec3(4, 1, 1), {16, 4, 4});
      m.discard_change();
      FemSimulationOptions opt;
      opt.kind = kind;
      opt.formulation = f;
      opt.cg.tolerance = 1e-8;
      opt.cg.max_iterations = 5000;
      opt.cg.preconditioner = pc;
      opt.cholesky.settle_frames = 0;     // the stale factor preconditions through the cuts
      opt.cholesky.settle_with_amg = false;
      FemSimulation sim(m, table(1e5, 0.45), opt);  // check_equals_direct's material
      fix_ends(m, sim);
      std::vector<VertexId> top;
      for (VertexId v : m.vertices())
        if (m.rest(v).z() > 1 - 1e-9) top.push_back(v);
      for (VertexId v : top) sim.set_force(v, Vec3(0, 0, -2));
      REQUIRE(sim.step().info == SolveInfo::Success);
      for (int depth = 1; depth <= 3; ++depth) {
        crack(m, 0, 2.0, 2, 1.0 - 0.25 * depth - 1e-3);
        sim.apply(m.take_change());
        const FrameStats& st = sim.step();
        INFO("depth " << depth << ": " << st.message);
        CHECK(st.info == SolveInfo::Success);
      }
      check_equals_direct(m, opt, top, sim);
      if (pc == Preconditioner::Amg) {
        CHECK(sim.amg()->patches() >= 1);
        CHECK(sim.amg()->failed_patches() == 0);
      }
    }
}

// After random edits and a crack, the locally updated model equals one built from scratch.
inline void check_local_updates(Formulation f) {
  for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
    INFO("kind " << int(kind));
    TetMesh m = make_box(Vec3(1, 1.5, 1), {5, 6, 5});
    jitter(m, 0.25, 21);
    for (TetId t : m.tets())
      if (t.idx() % 4 == 0) m.set_label(t, 2);
    m.discard_change();
    const MaterialTable mats = two_materials();
    FemModel local(m, mats, kind, f);
    std::mt19937 rng(77), check_rng(5);
    Eigen::VectorXd u = random_vector(local.rows(), rng, 0.05);
    local.update_rotations(u);
    auto compare = [&](const char* what) {
      m.validate();
      FemModel scratch(m, mats, kind, f);
      Eigen::VectorXd us = u.head(3 * m.vertex_capacity());
      local.update_rotations(u);
      scratch.update_rotations(us);
      INFO(what << ", " << m.num_tets() << " tets");
      CHECK(local.num_edges() == scratch.num_edges());
      CHECK(model_difference(local, scratch, m, check_rng) <= 1e-12);
    };
    int edits = 0;
    for (int batch = 0; edits < 1500; ++batch) {
      for (int k = 0; k < 1 + batch % 5; ++k) edits += random_edit(m, rng, true);
      const TopologyChange change = m.take_change();
      local.apply(change);
      interpolate_added_vertices(change, local.vertex_slots(), u);
      if (batch % 100 == 0) compare("random edits");
    }
    // A crack deepened cell by cell; without update_rotations in between for the linear model
    // (the blocks after apply() alone must be current).
    for (int depth = 1; depth <= 3; ++depth) {
      crack(m, 0, 0.5, 2, 1.0 - 0.2 * depth - 1e-3);
      const TopologyChange change = m.take_change();
      local.apply(change);
      interpolate_added_vertices(change, local.vertex_slots(), u);
      if (kind == FemKind::Linear) {
        FemModel scratch(m, mats, kind, f);
        CHECK(model_difference(local, scratch, m, check_rng) <= 1e-12);
      }
    }
    compare("crack");
  }
}

}  // namespace smoothed

}  // namespace incise::testing
