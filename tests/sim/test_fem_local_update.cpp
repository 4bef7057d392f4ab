// Local updates: after thousands of random edits fed through TopologyChange, the locally
// updated FEM model equals one built from scratch, the displacement field is interpolated onto
// new vertices, and the work per update does not grow with mesh size.
#include <catch2/catch.hpp>

#include <random>

#include "mesh/generate.h"
#include "sim/fem/fem_model.h"
#include "sim/fem/fem_simulation.h"
#include "tests/sim/fem_test_util.h"
#include "testing/draws.h"

using namespace incise;
using namespace incise::testing;

namespace {

MaterialTable two_materials() {
  Material soft;
  soft.young = 2e4;
  soft.poisson = 0.45;
  soft.density = 900;
  Material hard = soft;
  hard.young = 5e7;
  hard.poisson = 0.2;
  hard.density = 1900;
  MaterialTable t(soft);
  t.set(2, hard);
  return t;
}

// Relative difference of K*x, diag and mass between two models over the mesh's vertex range.
double model_difference(const FemModel& a, const FemModel& b, const TetMesh& m, std::mt19937& rng) {
  std::normal_distribution<double> nd;
  const Eigen::Index n = Eigen::Index(3 * m.vertex_capacity());
  Eigen::VectorXd xa = Eigen::VectorXd::Zero(a.rows()), xb = Eigen::VectorXd::Zero(b.rows()), ya, yb;
  for (Eigen::Index i = 0; i < n; ++i) xa[i] = xb[i] = nd(rng);
  a.multiply(xa, ya);
  b.multiply(xb, yb);
  double d = (ya.head(n) - yb.head(n)).norm() / yb.head(n).norm();
  d = std::max(d, (a.diagonal().head(n) - b.diagonal().head(n)).norm() / b.diagonal().head(n).norm());
  d = std::max(d, (a.lumped_mass().head(n) - b.lumped_mass().head(n)).norm() / b.lumped_mass().head(n).norm());
  // Slots beyond the mesh (geometric growth) stay empty.
  if (a.rows() > n) d = std::max(d, ya.tail(a.rows() - n).norm() + a.diagonal().tail(a.rows() - n).norm());
  return d;
}

}  // namespace

TEST_CASE("locally updated FEM model equals one built from scratch after thousands of edits", "[fem][local]") {
  for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
    TetMesh m = make_box(Vec3(1, 1.5, 1), {5, 6, 5});
    jitter(m, 0.25, 21);
    for (TetId t : m.tets())
      if (t.idx() % 4 == 0) m.set_label(t, 2);
    m.discard_change();
    const MaterialTable mats = two_materials();
    FemModel local(m, mats, kind);
    std::mt19937 rng(77), check_rng(5);
    std::normal_distribution<double> nd;
    Eigen::VectorXd u;  // a displacement with large rotations, carried through the edits
    auto refresh_u = [&] {
      u = Eigen::VectorXd::Zero(local.rows());
      for (VertexId v : m.vertices()) u.segment<3>(3 * v.idx()) = 0.05 * draw_vec3(nd, rng);
    };
    refresh_u();
    local.update_rotations(u);
    int edits = 0;
    for (int batch = 0; edits < 3000; ++batch) {
      const int in_batch = 1 + batch % 5;
      for (int k = 0; k < in_batch; ++k) edits += random_edit(m, rng, true);
      const TopologyChange change = m.take_change();
      local.apply(change);
      interpolate_added_vertices(change, local.vertex_slots(), u);
      if (batch % 150 == 0 || edits >= 3000) {
        m.validate();
        FemModel scratch(m, mats, kind);
        Eigen::VectorXd us = u.head(3 * m.vertex_capacity());
        local.update_rotations(u);
        scratch.update_rotations(us);
        INFO("after " << edits << " edits, " << m.num_tets() << " tets");
        CHECK(model_difference(local, scratch, m, check_rng) <= 1e-12);
      }
    }
  }
}

TEST_CASE("new vertices inherit interpolated displacement, velocity and constraints", "[fem][local]") {
  TetMesh m = make_box(Vec3(2, 1, 1), {6, 3, 3});
  jitter(m, 0.2, 3);
  m.discard_change();
  FemSimulationOptions opt;
  opt.dynamic = true;
  FemSimulation sim(m, two_materials(), opt);
  Eigen::Matrix3d a;
  a << 0.1, 0.2, -0.1, 0.05, -0.3, 0.2, 0.0, 0.1, 0.15;
  auto field = [&](const Vec3& x) -> Vec3 { return a * x + Vec3(1, 2, 3); };
  for (VertexId v : m.vertices()) {
    sim.displacement().segment<3>(3 * v.idx()) = field(m.rest(v));
    if (m.rest(v).x() < 1e-9) sim.fix(v);
  }
  std::mt19937 rng(9);
  for (int i = 0; i < 1500; ++i) {
    random_edit(m, rng, false);
    if (i % 3 == 2) sim.apply(m.take_change());
  }
  sim.apply(m.take_change());
  double err = 0;
  for (VertexId v : m.vertices()) err = std::max(err, (sim.displacement().segment<3>(3 * v.idx()) - field(m.rest(v))).norm());
  CHECK(err <= 1e-12 * 10);
  // Vertices created on the fixed face (all parents fixed) are fixed; others are free.
  int on_face = 0;
  for (VertexId v : m.vertices()) {
    const bool face = m.rest(v).x() < 1e-12;
    if (face) {
      ++on_face;
      CHECK(sim.is_constrained(v));
    } else {
      CHECK_FALSE(sim.is_constrained(v));
    }
  }
  CHECK(on_face > 16);
  // The edited simulation still runs.
  const FrameStats& st = sim.step();
  CHECK(st.info == SolveInfo::Success);
}

TEST_CASE("FEM local updates: work per update does not grow with mesh size", "[fem][local][locality]") {
  auto work_per_update = [](int n) {
    TetMesh m = make_box(Vec3(1, 1, 1), {n, n, n});
    m.discard_change();
    FemModel model(m, two_materials());
    model.reset_work();
    std::mt19937 rng(3);
    for (int i = 0; i < 2000; ++i) {
      random_edit(m, rng, true);
      model.apply(m.take_change());
    }
    const FemWork& w = model.work();
    return std::pair<double, double>(double(w.tets_recomputed) / double(w.updates),
                                     double(w.vertices_updated) / double(w.updates));
  };
  const auto [tets_small, verts_small] = work_per_update(6);    // 1.3k tets
  const auto [tets_large, verts_large] = work_per_update(45);   // 547k tets
  WARN("per update: tets recomputed " << tets_small << " (1.3k tets) vs " << tets_large << " (547k tets); vertices "
                                      << verts_small << " vs " << verts_large);
  CHECK(tets_large < 1.5 * tets_small);
  CHECK(verts_large < 1.5 * verts_small);
  CHECK(tets_large > 0);
}
