// The aggregation multigrid preconditioner: M^-1 symmetric positive definite, CG with it equals
// the direct solution before and after cuts, aggregates follow the cut, and it needs far fewer
// iterations than block-Jacobi on a long cantilever.
#include <catch2/catch.hpp>

#include <random>

#include "mesh/generate.h"
#include "sim/fem/aggregation_amg.h"
#include "sim/fem/fem_simulation.h"
#include "sim/linalg/vertex_aggregation.h"
#include "tests/sim/fem_test_util.h"

using namespace incise;
using namespace incise::testing;

namespace {

using Cycle = AggregationAmgOptions::Cycle;

std::vector<VertexId> top_of(const TetMesh& m) {
  std::vector<VertexId> top;
  for (VertexId v : m.vertices())
    if (m.rest(v).z() > 1 - 1e-9) top.push_back(v);
  return top;
}

// The cut tests' beam (4 x 1 x 1 in 16 x 4 x 4 cells, no change pending) and CG to 1e-8.
TetMesh cut_beam() {
  TetMesh m = make_box(Vec3(4, 1, 1), {16, 4, 4});
  m.discard_change();
  return m;
}

FemSimulationOptions cg_options(FemKind kind, Preconditioner pc) {
  FemSimulationOptions opt;
  opt.kind = kind;
  opt.cg.tolerance = 1e-8;
  opt.cg.preconditioner = pc;
  return opt;
}

// The face-connected part of each tet.
std::vector<int> parts(const TetMesh& m) {
  std::vector<int> part(m.tet_capacity(), -1);
  int n = 0;
  for (TetId s : m.tets()) {
    if (part[s.idx()] >= 0) continue;
    std::vector<TetId> stack{s};
    part[s.idx()] = n;
    while (!stack.empty()) {
      const TetId t = stack.back();
      stack.pop_back();
      for (int f = 0; f < 4; ++f) {
        const TetId nb = m.neighbor(t, f);
        if (nb.is_valid() && part[nb.idx()] < 0) part[nb.idx()] = n, stack.push_back(nb);
      }
    }
    ++n;
  }
  return part;
}

// r1 . M^-1 r2 = r2 . M^-1 r1 and r . M^-1 r > 0 for random residuals on the free unknowns,
// and M^-1 r is zero on kept ones: M^-1 as CG used it in the last frame.
void check_spd(const FemSimulation& sim) {
  const auto& free = sim.free_mask();
  std::mt19937 rng(5);
  auto random_residual = [&] { return random_free_residual(free, rng); };
  for (int trial = 0; trial < 5; ++trial) {
    const Eigen::VectorXd r1 = random_residual(), r2 = random_residual();
    Eigen::VectorXd z1, z2;
    sim.amg()->apply(r1, z1);
    sim.amg()->apply(r2, z2);
    const double a = r1.dot(z2), b = r2.dot(z1);
    CHECK(std::abs(a - b) <= 1e-10 * std::sqrt(r1.dot(z1) * r2.dot(z2)));
    CHECK(r1.dot(z1) > 0);
    int nonzero_kept = 0;
    for (std::size_t i = 0; i < free.size(); ++i) nonzero_kept += !free[i] && z1[Eigen::Index(i)] != 0;
    CHECK(nonzero_kept == 0);
  }
}

}  // namespace

TEST_CASE("aggregation: every free vertex in one aggregate, fixed ones in none", "[amg]") {
  TetMesh m = make_box(Vec3(4, 1, 1), {16, 4, 4});
  std::vector<std::uint8_t> eligible(m.vertex_capacity(), 1);
  for (VertexId v : m.vertices())
    if (m.rest(v).x() < 1e-9) eligible[v.idx()] = 0;
  for (int ring : {1, 2}) {
    const VertexAggregates a = aggregate_vertices(m, eligible, ring);
    std::vector<int> seen(m.vertex_capacity(), 0);
    for (std::size_t i = 0; i < a.count(); ++i)
      for (std::uint32_t v : a.members[i]) {
        CHECK(a.of[v] == int(i));
        ++seen[v];
      }
    for (VertexId v : m.vertices()) CHECK(seen[v.idx()] == (eligible[v.idx()] ? 1 : 0));
    // Aggregates of several vertices (the rigid modes need them): a few percent of the vertices.
    CHECK(a.count() < m.num_vertices() / (ring == 1 ? 5 : 15));
  }
}

TEST_CASE("amg: ring 0 aggregates 2 rings, or 3 where 2 leave too many aggregates, and patches keep it",
          "[amg][preconditioner][cut]") {
  for (int above : {100000, 5}) {
    INFO("ring 3 above " << above << " aggregates");
    TetMesh m = cut_beam();
    FemSimulationOptions opt = cg_options(FemKind::Corotational, Preconditioner::Amg);
    opt.amg.ring3_above = above;
    FemSimulation sim(m, table(1e5, 0.45), opt);
    fix_ends(m, sim);
    const std::vector<VertexId> top = top_of(m);
    for (VertexId v : top) sim.set_force(v, Vec3(0, 0, -2));
    REQUIRE(sim.step().info == SolveInfo::Success);
    // What the explicit rings give on the same free vertices.
    std::vector<std::uint8_t> eligible(m.vertex_capacity(), 0);
    for (VertexId v : m.vertices())
      eligible[v.idx()] = sim.free_mask()[3 * v.idx()] && sim.free_mask()[3 * v.idx() + 1] && sim.free_mask()[3 * v.idx() + 2];
    const std::size_t ring2 = aggregate_vertices(m, eligible, 2).count(), ring3 = aggregate_vertices(m, eligible, 3).count();
    REQUIRE(ring3 < ring2);
    REQUIRE(ring2 > 5);
    const int want = ring2 > std::size_t(above) ? 3 : 2;
    CHECK(sim.amg()->ring() == want);
    CHECK(sim.amg()->aggregates().count() == (want == 3 ? ring3 : ring2));
    crack(m, 0, 2.0, 2, 0.5);
    sim.apply(m.take_change());
    CHECK(sim.step().info == SolveInfo::Success);
    CHECK(sim.amg()->patches() == 1);
    CHECK(sim.amg()->build_stats().ring == want);
    check_equals_direct(m, opt, top, sim);
  }
}

TEST_CASE("amg: M^-1 is symmetric positive definite", "[amg][preconditioner]") {
  TetMesh m = make_box(Vec3(4, 1, 1), {16, 4, 4});
  jitter(m, 0.25, 7);
  // block: the coarse matrix's block Cholesky (small coarse levels), or (0) the general
  // sparse factor that larger ones get.
  for (int block : {700, 0})
  for (Cycle cycle : {Cycle::Multiplicative, Cycle::Additive})
    for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
      FemSimulationOptions opt;
      opt.kind = kind;
      opt.cg.tolerance = 1e-10;
      opt.cg.preconditioner = Preconditioner::Amg;
      opt.amg.cycle = cycle;
      opt.amg.block_factor_aggregates = block;
      FemSimulation sim(m, table(1e5, 0.45), opt);
      fix_ends(m, sim);
      for (VertexId v : top_of(m)) sim.set_force(v, Vec3(0, 3e3, -2e3));  // large: rotations
      for (int f = 0; f < 3; ++f) REQUIRE(sim.step().info == SolveInfo::Success);
      REQUIRE(sim.amg() != nullptr);
      REQUIRE(sim.amg()->build_stats().factor_ok);
      CHECK(sim.amg()->build_stats().block_factor == (block > 0));
      INFO("cycle " << int(cycle) << ", kind " << int(kind) << ", block factor " << block);
      check_spd(sim);
    }
}

TEST_CASE("amg: CG equals the direct solution through cuts, aggregates never span the cut", "[amg][preconditioner][cut]") {
  for (int block : {700, 0})
  for (Cycle cycle : {Cycle::Multiplicative, Cycle::Additive})
    for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
      INFO("cycle " << int(cycle) << ", kind " << int(kind) << ", block factor " << block);
      TetMesh m = cut_beam();
      FemSimulationOptions opt = cg_options(kind, Preconditioner::Amg);
      opt.amg.cycle = cycle;
      opt.amg.block_factor_aggregates = block;
      FemSimulation sim(m, table(1e5, 0.45), opt);
      fix_ends(m, sim);
      const std::vector<VertexId> top = top_of(m);
      for (VertexId v : top) sim.set_force(v, Vec3(0, 0, -2));
      REQUIRE(sim.step().info == SolveInfo::Success);
      // Deepen the cut a cell per frame, down through the whole height: two halves, each held
      // by its end.
      for (int depth = 1; depth <= 4; ++depth) {
        crack(m, 0, 2.0, 2, 1.0 - 0.25 * depth - 1e-3);
        sim.apply(m.take_change());
        const FrameStats& st = sim.step();
        INFO("depth " << depth << ": " << st.message);
        CHECK(st.info == SolveInfo::Success);
      }
      m.validate();
      const std::vector<int> part = parts(m);
      const VertexAggregates& agg = sim.amg()->aggregates();
      int split = 0;
      for (const auto& members : agg.members) {
        const int p = part[m.incident_tets(VertexId(members.front()))[0].idx()];
        for (std::uint32_t v : members) split += part[m.incident_tets(VertexId(v))[0].idx()] != p;
      }
      CHECK(split == 0);
      // The cuts were patched locally (one build, then a patch per cut), and M^-1 is still SPD.
      CHECK(sim.amg()->builds() == 1);
      CHECK(sim.amg()->patches() == 4);
      CHECK(sim.amg()->build_stats().block_factor == (block > 0));
      check_spd(sim);
      check_equals_direct(m, opt, top, sim);
    }
}

TEST_CASE("amg: far fewer CG iterations than block-Jacobi on a long cantilever", "[amg][preconditioner]") {
  // 40 x 4 x 4 cells (3,840 tets), linear, cold start, tolerance 1e-8: block-Jacobi's count
  // grows with the length squared, the coarse level's does not.
  TetMesh m = make_box(Vec3(10, 1, 1), {40, 4, 4});
  int it[2] = {0, 0};
  Eigen::VectorXd u[2];
  const Preconditioner pcs[2] = {Preconditioner::BlockJacobi, Preconditioner::Amg};
  for (int i = 0; i < 2; ++i) {
    FemSimulationOptions opt;
    opt.cg.tolerance = 1e-8;
    opt.cg.max_iterations = 100000;
    opt.cg.preconditioner = pcs[i];
    FemSimulation sim(m, table(1e5, 0.3), opt);
    for (VertexId v : m.vertices()) {
      if (m.rest(v).x() < 1e-9) sim.fix(v);
      if (m.rest(v).z() > 1 - 1e-9) sim.set_force(v, Vec3(0, 0, -1));
    }
    const FrameStats& st = sim.step();
    REQUIRE(st.info == SolveInfo::Success);
    it[i] = st.iterations;
    u[i] = sim.displacement();
  }
  WARN("block-Jacobi " << it[0] << " iterations, amg " << it[1]);
  CHECK(it[1] * 5 <= it[0]);
  CHECK((u[1] - u[0]).norm() <= 1e-6 * u[0].norm());
}

TEST_CASE("settle policy with amg: the multigrid while the blade moves, the factor once settled", "[amg][cholesky][cut]") {
  // The same cuts with block-Jacobi (the default settle policy) and with the multigrid.
  int cut_iterations[2] = {0, 0};
  for (bool with_amg : {false, true}) {
    INFO("settle_with_amg " << with_amg);
    TetMesh m = cut_beam();
    FemSimulationOptions opt = cg_options(FemKind::Corotational, Preconditioner::Cholesky);
    opt.cholesky.background = false;  // deterministic: a started factorization lands in the same frame
    opt.cholesky.settle_frames = 2;
    opt.cholesky.settle_with_amg = with_amg;
    FemSimulation sim(m, table(1e5, 0.45), opt);
    fix_ends(m, sim);
    const std::vector<VertexId> top = top_of(m);
    for (VertexId v : top) sim.set_force(v, Vec3(0, 0, -2));
    REQUIRE(sim.step().info == SolveInfo::Success);
    REQUIRE((sim.amg() != nullptr) == with_amg);
    if (with_amg) CHECK(sim.amg()->builds() == 0);  // the factor preconditions: the multigrid is not built
    for (int depth = 1; depth <= 3; ++depth) {
      crack(m, 0, 2.0, 2, 1.0 - 0.25 * depth - 1e-3);
      sim.apply(m.take_change());
      const FrameStats& st = sim.step();
      CHECK(st.info == SolveInfo::Success);
      CHECK(sim.cholesky()->settling());
      cut_iterations[with_amg] += st.iterations;
    }
    if (with_amg) {
      CHECK(sim.amg()->builds() == 1);
      CHECK(sim.amg()->patches() == 2);
    }
    int frames = 0;
    while (sim.cholesky()->settling() && frames < 5) {
      CHECK(sim.step().info == SolveInfo::Success);
      ++frames;
    }
    CHECK_FALSE(sim.cholesky()->settling());
    check_equals_direct(m, opt, top, sim);
  }
  WARN("iterations over the cut frames: block-Jacobi " << cut_iterations[0] << ", amg " << cut_iterations[1]);
  CHECK(cut_iterations[1] * 3 <= cut_iterations[0]);
}

TEST_CASE("amg: the coarse matrix is the Galerkin product P^T K P through cuts, nodal-averaged too",
          "[amg][preconditioner][cut]") {
  // The additive cycle is z = S r + P A_c^-1 P^T r. For u = P y (here a translation per
  // aggregate: in every aggregate's span) and r = K u on the free unknowns, A_c = P^T K P gives
  // z - S r = u exactly; a coarse row left stale by a patch, or a missing part of K (the
  // nodal-averaged volumetric coupling between aggregates), does not. S is a block-Jacobi set up
  // on the same operator, as the multigrid's own smoother.
  for (Formulation form : {Formulation::Standard, Formulation::NodalAveraged})
    for (int block : {700, 0}) {
      INFO("formulation " << formulation_name(form) << ", block factor " << block);
      TetMesh m = cut_beam();
      FemSimulationOptions opt = cg_options(FemKind::Linear, Preconditioner::Amg);  // no rotations to refresh: every cut is a patch
      opt.formulation = form;
      opt.amg.block_factor_aggregates = block;
      FemSimulation sim(m, table(1e5, 0.45), opt);
      fix_ends(m, sim);
      for (VertexId v : top_of(m)) sim.set_force(v, Vec3(0, 1, -2));
      REQUIRE(sim.step().info == SolveInfo::Success);
      std::mt19937 rng(11);
      std::uniform_real_distribution<double> d(-1, 1);
      auto check_galerkin = [&]() {
        const VertexAggregates& agg = sim.amg()->aggregates();
        std::vector<Vec3> t(agg.count());
        for (Vec3& x : t) x = Vec3(d(rng), d(rng), d(rng));
        Eigen::VectorXd u = Eigen::VectorXd::Zero(sim.model().rows()), r, z, zs;
        for (std::size_t v = 0; v < agg.of.size(); ++v)
          if (agg.of[v] >= 0) u.segment<3>(3 * Eigen::Index(v)) = t[std::size_t(agg.of[v])];
        sim.model().multiply(u, r);
        for (std::size_t i = 0; i < sim.free_mask().size(); ++i)
          if (!sim.free_mask()[i]) r[Eigen::Index(i)] = 0;
        sim.amg()->apply(r, z);
        BlockJacobi smoother;
        smoother.setup(sim.model(), &sim.free_mask());
        smoother.apply(r, zs);
        CHECK((z - zs - u).norm() <= 1e-8 * u.norm());
      };
      check_galerkin();
      for (int depth = 1; depth <= 3; ++depth) {
        crack(m, 0, 2.0, 2, 1.0 - 0.25 * depth - 1e-3);
        sim.apply(m.take_change());
        REQUIRE(sim.step().info == SolveInfo::Success);
        check_galerkin();
      }
      CHECK(sim.amg()->builds() == 1);
      CHECK(sim.amg()->patches() == 3);
    }
}
