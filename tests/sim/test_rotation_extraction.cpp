// Warm-started rotation extraction (sim/fem/rotation_extraction.h) against the exact polar
// decomposition: random deformations with large rotations, near-inverted and inverted
// elements, sequences of frames, and the corotational model and simulation built on it.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include <Eigen/SparseCore>
#include <tbb/global_control.h>

#include "mesh/generate.h"
#include "sim/fem/fem_model.h"
#include "sim/fem/fem_simulation.h"
#include "sim/fem/rotation_extraction.h"
#include "tests/sim/fem_test_util.h"
#include "testing/draws.h"

using namespace incise;
using namespace incise::testing;

namespace {

Eigen::Quaterniond random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> nd;
  return draw_quaternion(nd, rng).normalized();
}

// A rotation by `angle` about a random axis.
Eigen::Quaterniond random_turn(std::mt19937& rng, double angle) {
  std::normal_distribution<double> nd;
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, draw_vec3(nd, rng).normalized()));
}

// F = Q U diag(s) V^T: a rotation Q times a stretch with singular values s (a negative one
// inverts the element).
Eigen::Matrix3d deformation(std::mt19937& rng, const Eigen::Vector3d& s) {
  const Eigen::Matrix3d q = random_rotation(rng).toRotationMatrix(), uu = random_rotation(rng).toRotationMatrix();
  return q * uu * s.asDiagonal() * uu.transpose();
}

double angle_between(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle();
}

bool proper_rotation(const Eigen::Matrix3d& r) {
  return r.allFinite() && (r.transpose() * r - Eigen::Matrix3d::Identity()).norm() < 1e-12 &&
         std::abs(r.determinant() - 1) < 1e-12;
}

// Runs the lane iteration alone (no fallback) on one F from `start`: converged, and the result.
std::pair<bool, Eigen::Matrix3d> iterate(const Eigen::Matrix3d& f, const Eigen::Quaterniond& start, int steps = 8) {
  RotationLanes l;
  for (std::size_t k = 0; k < RotationLanes::kLanes; ++k) {
    for (int i = 0; i < 9; ++i) l.f[i][k] = f(i / 3, i % 3);
    l.q[0][k] = start.w(), l.q[1][k] = start.x(), l.q[2][k] = start.y(), l.q[3][k] = start.z();
  }
  refine_rotations(l, steps, 1e-6);
  const Eigen::Quaterniond q(l.q[0][0], l.q[1][0], l.q[2][0], l.q[3][0]);
  return {l.step[0] <= 1e-6, q.toRotationMatrix()};
}

}  // namespace

TEST_CASE("warm-started rotations agree with the exact polar decomposition on random deformations",
          "[fem][rotation]") {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> stretch(0.3, 3.0), unit(0, 1);
  struct Family {
    const char* name;
    std::function<Eigen::Vector3d()> sigma;
  };
  const std::vector<Family> families{
      {"well-shaped", [&] { return draw_vec3(stretch, rng); }},
      {"near-inverted", [&] {
         const double z = 1e-3 + 0.01 * unit(rng), y = stretch(rng), x = stretch(rng);
         return Eigen::Vector3d(x, y, z);
       }},
      // Inverted with the flipped singular value well below the others: the closest proper
      // rotation is well determined.
      {"inverted", [&] {
         const double a = 0.5 + unit(rng), b = 0.5 + unit(rng);
         return Eigen::Vector3d(a, b, -0.4 * std::min(a, b) * unit(rng));
       }},
  };
  for (const Family& fam : families) {
    int converged = 0, cases = 0;
    double worst = 0;
    for (int i = 0; i < 400; ++i) {
      const Eigen::Matrix3d f = deformation(rng, fam.sigma());
      const Eigen::Matrix3d exact = polar_rotation(f);
      REQUIRE(proper_rotation(exact));
      // Starts: near the answer (a previous frame), far from it, and the identity (a new tet).
      for (double off : {1e-3, 0.05, 0.5, -1.0}) {
        const Eigen::Quaterniond start =
            off < 0 ? Eigen::Quaterniond::Identity() : Eigen::Quaterniond(exact) * random_turn(rng, off);
        bool used_exact = false;
        const Eigen::Matrix3d r = refine_rotation(f, start, {}, &used_exact).toRotationMatrix();
        INFO(fam.name << " case " << i << " start offset " << off << ": F =\n" << f);
        CHECK(proper_rotation(r));
        worst = std::max(worst, angle_between(r, exact));
        // The iteration alone (no fallback) converges to the same rotation wherever it says so.
        const auto [ok, it] = iterate(f, start);
        if (ok) CHECK(angle_between(it, exact) < 1e-9);
        ++cases;
        converged += ok;
      }
    }
    INFO(fam.name << ": " << converged << " of " << cases << " converged without the fallback");
    CHECK(worst < 1e-9);
    // Warm starts (two of the four starts) converge on their own nearly always.
    CHECK(converged >= cases / 2);
  }
}

TEST_CASE("rotation extraction of ambiguous and degenerate deformations is a proper rotation maximizing tr(R^T F)",
          "[fem][rotation]") {
  std::mt19937 rng(3);
  std::vector<Eigen::Matrix3d> fs{Eigen::Matrix3d::Zero(), Eigen::Matrix3d::Identity() * 1e-300,
                                  deformation(rng, Eigen::Vector3d(1, 0, 0)),           // a line
                                  deformation(rng, Eigen::Vector3d(1, 1, 0)),           // flat
                                  deformation(rng, Eigen::Vector3d(1, 0.5, -0.5)),      // inverted, ambiguous
                                  deformation(rng, Eigen::Vector3d(-1, -1, -1)),        // point-reflected
                                  Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix()};
  for (const Eigen::Matrix3d& f : fs) {
    for (const Eigen::Quaterniond& start : {Eigen::Quaterniond::Identity(), random_rotation(rng)}) {
      const Eigen::Matrix3d r = refine_rotation(f, start).toRotationMatrix(), exact = polar_rotation(f);
      INFO("F =\n" << f);
      CHECK(proper_rotation(r));
      CHECK((r.transpose() * f).trace() >= (exact.transpose() * f).trace() - 1e-9 * (1 + f.norm()));
    }
  }
}

TEST_CASE("the warm-started iteration tracks the exact rotation over a sequence of frames", "[fem][rotation]") {
  std::mt19937 rng(8);
  for (int seq = 0; seq < 20; ++seq) {
    // A smoothly turning, stretching and at the end inverting element, 200 frames.
    const Eigen::Vector3d axis = random_rotation(rng).vec().normalized();
    const Eigen::Matrix3d u = random_rotation(rng).toRotationMatrix();
    const double speed = 0.01 + 0.05 * seq / 20.0;  // radians per frame
    Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
    int fallbacks = 0;
    for (int n = 0; n < 200; ++n) {
      const double t = n / 200.0;
      const Eigen::Vector3d s(1 + 0.5 * std::sin(7 * t), 1 - 0.4 * t, 1 - 1.3 * t * t);  // s3 < 0 after t ~ 0.88
      const Eigen::Matrix3d f =
          Eigen::AngleAxisd(speed * n, axis).toRotationMatrix() * u * s.asDiagonal() * u.transpose();
      bool used_exact = false;
      q = refine_rotation(f, q, {}, &used_exact);
      fallbacks += used_exact;
      INFO("sequence " << seq << " frame " << n);
      CHECK(angle_between(q.toRotationMatrix(), polar_rotation(f)) < 1e-9);
    }
    CHECK(fallbacks <= 2);  // s3 crossing zero: the rotation jumps there
  }
}

TEST_CASE("warm-started and exact rotation updates give the same corotational model", "[fem][rotation]") {
  TetMesh m = make_box(Vec3(3, 1, 1), {9, 3, 3});
  jitter(m, 0.2, 4);
  FemModel warm(m, table(1e6, 0.3), FemKind::Corotational), exact(m, table(1e6, 0.3), FemKind::Corotational);
  exact.set_warm_started_rotations(false);
  std::mt19937 rng(2);
  std::normal_distribution<double> nd;
  Eigen::VectorXd x(warm.rows()), yw, ye;
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] = nd(rng);
  // Twisted about x by up to 3 turns, bent, and at the end crushed (inverted elements).
  for (int n = 0; n <= 60; ++n) {
    const double t = n / 60.0;
    Eigen::VectorXd u = Eigen::VectorXd::Zero(warm.rows());
    for (VertexId v : m.vertices()) {
      const Vec3 p = m.rest(v);
      const Eigen::Matrix3d twist = Eigen::AngleAxisd(6 * M_PI * t * p.x() / 3, Vec3::UnitX()).toRotationMatrix();
      Vec3 d = twist * (p - Vec3(0, 0.5, 0.5)) + Vec3(0, 0.5, 0.5) - p + Vec3(0, 0, 0.3 * t * p.x() * p.x());
      if (n > 50) d.x() -= (n - 50) * 0.25 * p.x();  // crushed along x past inversion
      u.segment<3>(3 * v.idx()) = d;
    }
    warm.update_rotations(u);
    exact.update_rotations(u);
    INFO("frame " << n);
    double worst = 0;
    for (TetId t : m.tets()) {
      CHECK(proper_rotation(warm.rotation(t)));
      worst = std::max(worst, (warm.rotation(t) - exact.rotation(t)).norm());
    }
    CHECK(worst < 1e-9);
    CHECK((warm.diagonal() - exact.diagonal()).norm() <= 1e-12 * exact.diagonal().norm());
    for (VertexId v : m.vertices())
      CHECK((warm.diagonal_blocks()[v.idx()] - exact.diagonal_blocks()[v.idx()]).norm() <=
            1e-11 * exact.diagonal_blocks()[v.idx()].norm());
    warm.multiply(x, yw);
    exact.multiply(x, ye);
    CHECK((yw - ye).norm() <= 1e-10 * ye.norm());
    // b_R (summed per vertex in the rotation pass) against the per-tet formula.
    Eigen::VectorXd bw = Eigen::VectorXd::Zero(warm.rows()), be = Eigen::VectorXd::Zero(warm.rows());
    warm.add_rotation_rhs(bw);
    for (TetId t : m.tets()) {
      const Eigen::Matrix3d r = exact.rotation(t), h = Eigen::Matrix3d::Identity() - r.transpose();
      const double mu = Material{}.mu(), lambda = Material{}.lambda();
      const Eigen::Matrix3d eps = 0.5 * (h + h.transpose());
      const Eigen::Matrix3d p = exact.tet_volume(t) * r * (2 * mu * eps + lambda * eps.trace() * Eigen::Matrix3d::Identity());
      const auto& tv = m.tet_vertices(t);
      Eigen::Matrix3d dm;
      for (int j = 0; j < 3; ++j) dm.col(j) = m.rest(tv[j + 1]) - m.rest(tv[0]);
      const Eigen::Matrix3d g = dm.inverse();  // row j: grad N_{j+1}
      for (int j = 0; j < 3; ++j) {
        be.segment<3>(3 * tv[j + 1].idx()) += p * g.row(j).transpose();
        be.segment<3>(3 * tv[0].idx()) -= p * g.row(j).transpose();
      }
    }
    CHECK((bw - be).norm() <= 1e-9 * (1 + be.norm()));
    if (n > 0 && n < 50) CHECK(warm.rotation_stats().exact == 0);  // smooth frames: no fallback
  }
}

// The whole-mesh pass scatters each packet's corner terms into its vertices (slabs three apart
// on different threads, sim/fem/stiffness_kernel.h); checked against what does not share its code: the
// assembled K_R's diagonal blocks, b_R summed per tet, each tet's exact polar rotation of F.
TEST_CASE("the relinearization's diagonal blocks and b_R equal the assembled ones, on any thread count, through edits",
          "[fem][rotation]") {
  TetMesh m = make_box(Vec3(6, 1, 1), {40, 6, 6});  // 8,640 tets: above the kernel's serial limit
  jitter(m, 0.2, 9);
  m.discard_change();
  const Material mat{2e5, 0.35, 1000};
  FemModel one(m, MaterialTable(mat), FemKind::Corotational), two(m, MaterialTable(mat), FemKind::Corotational);
  Eigen::VectorXd u;
  auto deform = [&](double turns) {
    u = Eigen::VectorXd::Zero(two.rows());
    for (VertexId v : m.vertices()) {
      const Vec3 p = m.rest(v);
      const Eigen::Matrix3d r = Eigen::AngleAxisd(2 * M_PI * turns * p.x() / 6, Vec3::UnitX()).toRotationMatrix();
      u.segment<3>(3 * v.idx()) = r * (p - Vec3(0, 0.5, 0.5)) + Vec3(0, 0.5, 0.5) - p + Vec3(0, 0.05 * p.x() * p.x(), 0);
    }
  };
  auto relinearize = [&] {
    {
      tbb::global_control serial(tbb::global_control::max_allowed_parallelism, 1);
      one.update_rotations(u);
    }
    two.update_rotations(u);
  };
  auto check = [&](const char* when) {
    INFO(when << ", " << m.num_tets() << " tets");
    const Eigen::SparseMatrix<double> k = two.assemble();
    Eigen::VectorXd b1 = Eigen::VectorXd::Zero(one.rows()), b2 = Eigen::VectorXd::Zero(two.rows());
    one.add_rotation_rhs(b1);
    two.add_rotation_rhs(b2);
    Eigen::VectorXd be = Eigen::VectorXd::Zero(two.rows());
    double worst_angle = 0, worst_block = 0;
    std::size_t differ = 0;
    for (TetId t : m.tets()) {
      const auto& tv = m.tet_vertices(t);
      Eigen::Matrix3d dm, dx;
      for (int j = 0; j < 3; ++j) {
        dm.col(j) = m.rest(tv[j + 1]) - m.rest(tv[0]);
        dx.col(j) = dm.col(j) + u.segment<3>(3 * tv[j + 1].idx()) - u.segment<3>(3 * tv[0].idx());
      }
      const Eigen::Matrix3d g = dm.inverse();  // row j: grad N_{j+1}
      const Eigen::Matrix3d exact = polar_rotation(dx * g);
      worst_angle = std::max(worst_angle, Eigen::AngleAxisd(exact.transpose() * two.rotation(t)).angle());
      const Eigen::Matrix3d r = two.rotation(t), h = Eigen::Matrix3d::Identity() - r.transpose();
      const Eigen::Matrix3d eps = 0.5 * (h + h.transpose());
      const Eigen::Matrix3d p =
          dm.determinant() / 6 * r * (2 * mat.mu() * eps + mat.lambda() * eps.trace() * Eigen::Matrix3d::Identity());
      for (int j = 0; j < 3; ++j) {
        be.segment<3>(3 * tv[j + 1].idx()) += p * g.row(j).transpose();
        be.segment<3>(3 * tv[0].idx()) -= p * g.row(j).transpose();
      }
    }
    for (VertexId v : m.vertices()) {
      const Eigen::Index i = 3 * Eigen::Index(v.idx());
      const Eigen::Matrix3d assembled = Eigen::MatrixXd(k.block(i, i, 3, 3));
      worst_block = std::max(worst_block, (two.diagonal_blocks()[v.idx()] - assembled).norm() / assembled.norm());
      CHECK(two.diagonal().segment<3>(i) == two.diagonal_blocks()[v.idx()].diagonal());
      differ += one.diagonal_blocks()[v.idx()] != two.diagonal_blocks()[v.idx()];
    }
    CHECK(worst_angle < 1e-8);
    CHECK(worst_block < 1e-13);
    CHECK((b2 - be).norm() <= 1e-12 * be.norm());
    CHECK(differ == 0);  // bit for bit on one thread and two
    CHECK(b1 == b2);
  };
  for (double turns : {0.1, 0.3, 0.6}) {  // each start 0.2-0.3 turns from the last: Newton steps
    deform(turns);
    relinearize();
    check("twisted");
  }
  // Edits move tets between the kernel's slots (a removal swaps the last tet of its slab in)
  // and add vertices; the next relinearization scatters in the new order.
  std::mt19937 rng(4);
  for (int batch = 0; batch < 6; ++batch) {
    for (int e = 0; e < 40; ++e) random_edit(m, rng, true);
    const TopologyChange change = m.take_change();
    one.apply(change);
    two.apply(change);
    deform(0.6 + 0.02 * batch);
    relinearize();
  }
  check("after 240 edits");
}

TEST_CASE("a corotational simulation gives the same result with warm-started and exact rotations", "[fem][rotation]") {
  TetMesh m = make_box(Vec3(4, 1, 1), {16, 4, 4});
  auto run = [&](bool warm) {
    FemSimulationOptions opt;
    opt.kind = FemKind::Corotational;
    opt.cg.tolerance = 1e-10;
    opt.cg.preconditioner = Preconditioner::BlockJacobi;
    opt.nonlinear_iterations = 2;
    FemSimulation sim(m, table(1e5, 0.3), opt);
    sim.model().set_warm_started_rotations(warm);
    std::vector<VertexId> tip;
    for (VertexId v : m.vertices()) {
      if (m.rest(v).x() < 1e-9) sim.fix(v);
      if (m.rest(v).x() > 4 - 1e-9) tip.push_back(v);
    }
    for (int frame = 1; frame <= 30; ++frame) {  // the tip swept down and around: large rotations
      const double a = 0.05 * frame;
      for (VertexId v : tip) sim.prescribe(v, Vec3(-4 * (1 - std::cos(a)), 0, -4 * std::sin(a)));
      sim.step();
    }
    return Eigen::VectorXd(sim.displacement());
  };
  const Eigen::VectorXd uw = run(true), ue = run(false);
  CHECK((uw - ue).norm() <= 1e-7 * ue.norm());
}

TEST_CASE("tets added by edits start from the identity and reach the exact rotation, the others stay warm",
          "[fem][rotation][local]") {
  TetMesh m = make_box(Vec3(2, 1, 1), {8, 4, 4});
  jitter(m, 0.2, 6);
  m.discard_change();
  const MaterialTable mats = table(1e6, 0.3);
  FemModel model(m, mats, FemKind::Corotational);
  // Rigidly turned by 2.5 rad and slightly stretched: from the identity, the Newton steps cannot
  // reach it (M is not positive definite there), so new tets need the exact decomposition.
  const Eigen::Matrix3d q = Eigen::AngleAxisd(2.5, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  Eigen::VectorXd u = Eigen::VectorXd::Zero(model.rows());
  for (VertexId v : m.vertices()) {
    const Vec3 p = m.rest(v);
    u.segment<3>(3 * v.idx()) = q * Vec3(1.05 * p.x(), p.y(), p.z()) - p;
  }
  model.update_rotations(u);
  model.update_rotations(u);  // warm: nothing left to refine
  CHECK(model.rotation_stats().exact == 0);
  std::mt19937 rng(12);
  int edits = 0;
  while (edits < 20) edits += random_edit(m, rng, true);
  const TopologyChange change = m.take_change();
  model.apply(change);
  interpolate_added_vertices(change, model.vertex_slots(), u);
  model.update_rotations(u);
  const std::size_t fresh = change.added_tets.size();
  INFO(fresh << " tets added, " << model.rotation_stats().exact << " exact");
  CHECK(model.rotation_stats().exact > 0);
  CHECK(model.rotation_stats().exact <= fresh);  // only the new tets
  FemModel scratch(m, mats, FemKind::Corotational);
  scratch.set_warm_started_rotations(false);
  Eigen::VectorXd us = u.head(scratch.rows());
  scratch.update_rotations(us);
  double worst = 0;
  for (TetId t : m.tets()) worst = std::max(worst, (model.rotation(t) - scratch.rotation(t)).norm());
  CHECK(worst < 1e-9);
  for (VertexId v : m.vertices())
    CHECK((model.diagonal_blocks()[v.idx()] - scratch.diagonal_blocks()[v.idx()]).norm() <=
          1e-11 * scratch.diagonal_blocks()[v.idx()].norm());
}

TEST_CASE("partial rotation updates cover every tet in turn and end equal to a full update", "[fem][rotation]") {
  TetMesh m = make_box(Vec3(3, 1, 1), {9, 3, 3});
  jitter(m, 0.2, 4);
  for (Formulation f : {Formulation::Standard, Formulation::NodalAveraged}) {
    FemModel full(m, table(1e6, 0.3), FemKind::Corotational, f), part(m, table(1e6, 0.3), FemKind::Corotational, f);
    Eigen::VectorXd u = Eigen::VectorXd::Zero(full.rows());
    for (VertexId v : m.vertices()) {
      const Vec3 p = m.rest(v);
      const Eigen::Matrix3d twist = Eigen::AngleAxisd(0.8 * p.x(), Vec3::UnitX()).toRotationMatrix();
      u.segment<3>(3 * v.idx()) = twist * (p - Vec3(0, 0.5, 0.5)) + Vec3(0, 0.5, 0.5) - p;
    }
    full.update_rotations(u);
    const std::size_t packets = part.rotation_packets();
    REQUIRE(packets > 10);
    // Four calls of a third, wrapping past the end: after the first three every tet was
    // refreshed once (the fourth repeats some, at the same u).
    const std::size_t n = (packets + 2) / 3;
    std::size_t first = 0;
    for (int call = 0; call < 4; ++call, first += n) {
      part.update_rotations_partial(u, first, n);
      CHECK(part.rotation_stats().tets <= n * RotationLanes::kLanes);
      if (call == 0) {  // only the first third moved so far
        std::size_t moved = 0;
        for (TetId t : m.tets()) moved += (part.rotation(t) - Eigen::Matrix3d::Identity()).norm() > 1e-12;
        CHECK(moved <= n * RotationLanes::kLanes);
        CHECK(moved > 0);
      }
    }
    double worst = 0;
    for (TetId t : m.tets()) worst = std::max(worst, (part.rotation(t) - full.rotation(t)).norm());
    CHECK(worst < 1e-9);
    for (VertexId v : m.vertices())
      CHECK((part.diagonal_blocks()[v.idx()] - full.diagonal_blocks()[v.idx()]).norm() <=
            1e-11 * full.diagonal_blocks()[v.idx()].norm());
    Eigen::VectorXd x = Eigen::VectorXd::LinSpaced(full.rows(), -1, 1), yf, yp, bf = Eigen::VectorXd::Zero(full.rows()),
                    bp = Eigen::VectorXd::Zero(full.rows());
    full.multiply(x, yf);
    part.multiply(x, yp);
    CHECK((yf - yp).norm() <= 1e-10 * yf.norm());
    full.add_rotation_rhs(bf);
    part.add_rotation_rhs(bp);
    CHECK((bf - bp).norm() <= 1e-10 * (1 + bf.norm()));
  }
}

TEST_CASE("partial rotation updates refresh the nodal-averaged rotation rhs locally, equal to a full sum",
          "[fem][rotation]") {
  // Above the size where the volumetric passes run in parallel and the rhs is kept per vertex.
  TetMesh m = make_box(Vec3(3, 1, 1), {24, 8, 8});
  jitter(m, 0.2, 5);
  REQUIRE(m.num_tets() >= 8000);
  auto twist = [&](double turns) {
    Eigen::VectorXd u = Eigen::VectorXd::Zero(Eigen::Index(3 * m.vertex_capacity()));
    for (VertexId v : m.vertices()) {
      const Vec3 p = m.rest(v);
      const Eigen::Matrix3d r = Eigen::AngleAxisd(turns * p.x(), Vec3::UnitX()).toRotationMatrix();
      u.segment<3>(3 * v.idx()) = r * (p - Vec3(0, 0.5, 0.5)) + Vec3(0, 0.5, 0.5) - p;
    }
    return u;
  };
  const Eigen::VectorXd u0 = twist(0.3), u1 = twist(0.9);
  FemModel kept(m, table(1e6, 0.3), FemKind::Corotational, Formulation::NodalAveraged);
  REQUIRE(Eigen::Index(kept.num_dofs()) == u0.size());
  kept.update_rotations(u0);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(kept.rows());
  kept.add_rotation_rhs(b);  // summed in full, then kept
  const std::size_t packets = kept.rotation_packets(), n = (packets + 9) / 10;
  for (int calls = 1; calls <= 4; ++calls) {
    kept.reset_work();
    kept.update_rotations_partial(u1, std::size_t(calls - 1) * 3 * n, n);
    // A tenth of the tets (consecutive ids, near each other in the box): the blocks and rhs
    // sums of their neighbourhood only, not of the mesh.
    CHECK(kept.work().rotation_blocks > 0);
    CHECK(kept.work().rotation_rhs_sums >= kept.work().rotation_blocks);
    CHECK(kept.work().rotation_rhs_sums < m.num_vertices() / 2);
    Eigen::VectorXd bk = Eigen::VectorXd::Zero(kept.rows());
    kept.add_rotation_rhs(bk);
    // The same rotations in a model that sums the rhs in full: the same operations in the same
    // order, so the same bits.
    FemModel summed(m, table(1e6, 0.3), FemKind::Corotational, Formulation::NodalAveraged);
    summed.update_rotations(u0);
    for (int c = 1; c <= calls; ++c) summed.update_rotations_partial(u1, std::size_t(c - 1) * 3 * n, n);
    CHECK(summed.work().rotation_rhs_sums == 0);
    Eigen::VectorXd bs = Eigen::VectorXd::Zero(summed.rows());
    summed.add_rotation_rhs(bs);
    CHECK((bk - bs).cwiseAbs().maxCoeff() == 0.0);
    CHECK(bs.norm() > 0);
  }
}

TEST_CASE("a budget that cannot afford every rotation refreshes a share a frame and still converges", "[fem][rotation]") {
  TetMesh m = make_box(Vec3(4, 1, 1), {8, 2, 2});  // 192 tets: 24 packets, 12 cycles in 300 frames
  auto run = [&](double budget_ms, double share, std::vector<double>* shares) {
    FemSimulationOptions opt;
    opt.kind = FemKind::Corotational;
    opt.cg.tolerance = 1e-10;
    opt.cg.preconditioner = Preconditioner::BlockJacobi;
    opt.cg.budget_ms = budget_ms;
    opt.relinearize_share = share;
    FemSimulation sim(m, table(1e5, 0.3), opt);
    for (VertexId v : m.vertices()) {
      if (m.rest(v).x() < 1e-9) sim.fix(v);
      if (m.rest(v).x() > 4 - 1e-9) sim.prescribe(v, Vec3(-0.3, 0, -1.2));  // a large bend, held
    }
    for (int frame = 0; frame < 300; ++frame) {
      const FrameStats st = sim.step();
      if (shares) shares->push_back(st.relinearized);
    }
    return Eigen::VectorXd(sim.displacement());
  };
  // A tiny share of a generous budget: one packet's worth of rotations a frame at most, so
  // partial refreshes happen every frame after the first (which measures the cost).
  std::vector<double> shares;
  const Eigen::VectorXd partial = run(1000, 1e-9, &shares), whole = run(0, 0.5, nullptr);
  CHECK(shares.front() == 1.0);
  CHECK(*std::max_element(shares.begin() + 1, shares.end()) <= 1.0 / 24 + 1e-12);
  // Held still, the partial refreshes reach the same equilibrium (the rotations of every tet
  // were refreshed many times over 300 frames).
  CHECK((partial - whole).norm() <= 1e-6 * whole.norm());
}
