// The mixed u-p solver (sim/mixed_solver.h) against Poisson's ratio:
//  1. Lame's thick-walled cylinder (plane strain, inner pressure): error of the inner radial
//     displacement, mixed and standard tets, three meshes;
//  2. cantilever tip deflection against Timoshenko beam theory, mixed and standard, three meshes;
//  3. MINRES iterations and milliseconds per solve (cold start, tolerance 1e-6), Cholesky
//     (the first factorization waited for, inside the time), multigrid and block-Jacobi
//     displacement preconditioners;
//  4. frames: the cylinder's pressure ramped 5% a frame for 8 frames then held, each solve
//     warm-started from the last (iterations and ms per frame), and the same with a 20 ms budget
//     per frame (the residual after each budgeted frame; held loads resume the iteration).
//   bench_fem_mixed [--out DIR] [--quick] [--nu 0.3,0.45,0.49,0.4999,0.5] [--only lame|cantilever|minres|frames|product]
//                   [--cycle additive] [--ring 1]  (the multigrid of the minres section)
#include <cstdio>

#include <Eigen/SparseCholesky>

#include "bench/bench_common.h"
#include "sim/fem_model.h"
#include "tests/support/elasticity_cases.h"

using namespace incise;
using namespace incise::testing;
using namespace incise::bench;

namespace {

// Standard tets on the same problem (nu < 0.5 only): K u = f on the free unknowns, LDL^T.
double standard_lame(int nr, int nt, int nz, double nu) {
  const double a = 1, b = 2, h = 0.5, e = 1e4, p = 10;
  TetMesh m = make_quarter_tube(a, b, h, nr, nt, nz);
  FemModel model(m, MaterialTable(Material{e, nu, 1000}));
  MixedProblem pb = lame_problem(m, model.num_dofs(), a, h, p);
  Eigen::SparseMatrix<double> k = model.assemble();
  for (Eigen::Index i = 0; i < k.rows(); ++i)  // kept unknowns: identity rows, zero load
    if (!pb.free[std::size_t(i)] || model.diagonal()[i] == 0) {
      k.row(i) *= 0;
      k.col(i) *= 0;
      k.coeffRef(i, i) = 1;
      pb.f[i] = 0;
    }
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(k);
  const Eigen::VectorXd u = ldlt.solve(pb.f);
  double sum = 0;
  int count = 0;
  for (VertexId v : m.vertices()) {
    const Vec3 x = m.rest(v);
    if (std::abs(x.head<2>().norm() - a) > 1e-9) continue;
    sum += u.segment<2>(3 * Eigen::Index(v.idx())).dot(x.head<2>().normalized());
    ++count;
  }
  const double exact = lame_radial(a, b, e, nu, p, a);
  return std::abs(sum / count - exact) / exact;
}

double standard_cantilever(int n, double nu) {
  const double len = 8, h = 1, e = 1e6, load = -10, area = h * h;
  TetMesh m = make_box(Vec3(len, h, h), {int(len) * n, n, n});
  FemModel model(m, MaterialTable(Material{e, nu, 1000}));
  MixedProblem pb(model.num_dofs());
  for (VertexId v : m.vertices())
    if (m.rest(v).x() < 1e-9)
      for (int d = 0; d < 3; ++d) pb.keep(v, d);
  add_traction(m, pb, [&](const Vec3& x) { return x.x() > len - 1e-9; },
               [&](const Vec3&, const Vec3&) -> Vec3 { return Vec3(0, 0, load / area); });
  Eigen::SparseMatrix<double> k = model.assemble();
  for (Eigen::Index i = 0; i < k.rows(); ++i)
    if (!pb.free[std::size_t(i)]) {
      k.row(i) *= 0;
      k.col(i) *= 0;
      k.coeffRef(i, i) = 1;
      pb.f[i] = 0;
    }
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(k);
  const Eigen::VectorXd u = ldlt.solve(pb.f);
  double tip = 0;
  int count = 0;
  for (VertexId v : m.vertices())
    if (m.rest(v).x() > len - 1e-9) {
      tip += u[3 * Eigen::Index(v.idx()) + 2];
      ++count;
    }
  const double inertia = h * h * h * h / 12, g = e / (2 * (1 + nu)), kappa = 10 * (1 + nu) / (12 + 11 * nu);
  const double theory = load * len * len * len / (3 * e * inertia) + load * len / (kappa * g * area);
  return std::abs(tip / count - theory) / std::abs(theory);
}

// Frames of a ramped inner pressure on the cylinder: warm starts, then a wall-clock budget.
void frames(double nu, int nr, int nt, int nz, Csv* csv) {
  const double a = 1, b = 2, h = 0.5, e = 1e4, tol = 1e-9;
  TetMesh m = make_quarter_tube(a, b, h, nr, nt, nz);
  for (double budget : {0.0, 20.0}) {
    MixedOptions o;
    o.budget_ms = budget;
    MixedSolver solver(m, MixedMaterials(Material{e, nu, 1000}), FemKind::Linear, o);
    MixedProblem pb(solver.num_dofs());
    for (VertexId v : m.vertices()) {
      const Vec3 x = m.rest(v);
      if (std::abs(x.x()) < tol) pb.keep(v, 0);
      if (std::abs(x.y()) < tol) pb.keep(v, 1);
      if (std::abs(x.z()) < tol || std::abs(x.z() - h) < tol) pb.keep(v, 2);
    }
    std::printf("%8g budget %4g ms:", nu, budget);
    for (int frame = 0; frame < 14; ++frame) {
      MixedProblem load = pb;
      load.u = pb.u;  // the last solution: warm start
      const double p = 10 * (1 + 0.05 * std::min(frame, 7));  // ramp, then hold
      add_traction(m, load, [&](const Vec3& x) { return std::abs(x.head<2>().norm() - a) < 1e-9; },
                   [&](const Vec3&, const Vec3& n) -> Vec3 { return -p * n; });
      const MixedStats st = solver.solve(load.f, load.free, load.u);
      pb.u = load.u;
      std::printf(" %d it/%.1f ms/%.0e", st.iterations, st.solve_ms, st.relative_residual);
      if (csv) csv->row("frames", nu, budget, frame, st.relative_residual, NAN, "amg", st.iterations, st.solve_ms);
    }
    std::printf("\n");
  }
}

MixedOptions direct() {
  MixedOptions o;
  o.direct = true;
  return o;
}

}  // namespace

int main(int argc, char** argv) {
  Args args(argc, argv);
  const bool quick = args.flag("--quick");
  const std::vector<double> nus = args.list("--nu", "0.3,0.45,0.49,0.4999,0.5");
  const std::string out = args.get("--out", ""), only = args.get("--only", "");
  auto section = [&](const char* name) { return only.empty() || only == name; };
  std::unique_ptr<Csv> csv;
  if (!out.empty()) csv = std::make_unique<Csv>(out, "fem_mixed.csv", "case,nu,mesh,unknowns,mixed_error,standard_error,precond,iterations,ms");

  struct Mesh3 { int a, b, c; };
  const std::vector<Mesh3> tubes = quick ? std::vector<Mesh3>{{3, 6, 1}, {6, 12, 2}}
                                         : std::vector<Mesh3>{{3, 6, 1}, {6, 12, 2}, {12, 24, 4}};
  std::printf("1. Lame cylinder a=1 b=2, plane strain, inner pressure: |mean inner u_r - exact| / exact\n");
  std::printf("%8s %12s %12s %12s\n", "nu", "mesh", "mixed", "standard");
  for (double nu : nus)
    for (const Mesh3& t : tubes) {
      if (!section("lame")) break;
      const LameResult r = run_lame(t.a, t.b, t.c, nu, direct());
      const double s = nu < 0.5 ? standard_lame(t.a, t.b, t.c, nu) : NAN;
      const std::string mesh = std::to_string(t.a) + "x" + std::to_string(t.b) + "x" + std::to_string(t.c);
      std::printf("%8g %12s %12.4e %12.4e\n", nu, mesh.c_str(), r.error, s);
      if (csv) csv->row("lame", nu, mesh, 0, r.error, s, "direct", 0, r.stats.solve_ms);
    }

  const std::vector<int> beams = quick ? std::vector<int>{1, 2} : std::vector<int>{1, 2, 4, 6};
  std::printf("\n2. Cantilever 8x1x1, tip shear: |tip - Timoshenko| / |Timoshenko|\n");
  std::printf("%8s %6s %12s %12s\n", "nu", "cells", "mixed", "standard");
  for (double nu : nus)
    for (int n : beams) {
      if (!section("cantilever")) break;
      const CantileverResult r = run_cantilever(n, nu, direct());
      const double s = nu < 0.5 ? standard_cantilever(n, nu) : NAN;
      std::printf("%8g %6d %12.4e %12.4e\n", nu, n, r.error, s);
      if (csv) csv->row("cantilever", nu, n, 0, r.error, s, "direct", 0, r.stats.solve_ms);
    }

  std::printf("\n3. MINRES per solve (cold start, tolerance 1e-6): iterations and ms\n");
  std::printf("%8s %-14s %-14s %6s %10s %10s %10s\n", "nu", "case", "precond", "iters", "ms", "residual", "error");
  const Mesh3 big = quick ? Mesh3{6, 12, 2} : Mesh3{12, 24, 4};
  const int beam = quick ? 2 : 3;
  for (double nu : nus)
    for (MixedPreconditioner pc : {MixedPreconditioner::Cholesky, MixedPreconditioner::Amg, MixedPreconditioner::BlockJacobi}) {
      if (!section("minres")) break;
      MixedOptions o;
      o.preconditioner = pc;
      if (args.get("--cycle", "") == "additive") o.amg.cycle = AggregationAmgOptions::Cycle::Additive;
      if (args.num("--ring", 2) != 2) o.amg.ring = int(args.num("--ring", 2));
      o.max_iterations = 20000;
      const char* name = pc == MixedPreconditioner::Amg ? "amg" : pc == MixedPreconditioner::Cholesky ? "cholesky" : "block-jacobi";
      const LameResult l = run_lame(big.a, big.b, big.c, nu, o);
      std::printf("%8g %-14s %-14s %6d %10.2f %10.2e %10.2e\n", nu, "lame 12x24x4", name, l.stats.iterations,
                  l.stats.solve_ms, l.stats.relative_residual, l.error);
      const CantileverResult c = run_cantilever(beam, nu, o);
      std::printf("%8g %-14s %-14s %6d %10.2f %10.2e %10.2e\n", nu, "cantilever", name, c.stats.iterations,
                  c.stats.solve_ms, c.stats.relative_residual, c.error);
      if (csv) {
        csv->row("lame", nu, "big", 0, l.error, NAN, name, l.stats.iterations, l.stats.solve_ms);
        csv->row("cantilever", nu, beam, 0, c.error, NAN, name, c.stats.iterations, c.stats.solve_ms);
      }
    }
  if (only == "product") {  // not in the default run: the cost of one product, mixed vs K
    TetMesh m = make_quarter_tube(1, 2, 0.5, big.a, big.b, big.c);
    MixedSolver solver(m, MixedMaterials(Material{1e4, 0.5, 1000}));
    const Eigen::Index n = Eigen::Index(solver.num_dofs() + solver.vertex_slots());
    Eigen::VectorXd x = Eigen::VectorXd::Random(n), y, xu = x.head(Eigen::Index(solver.num_dofs())), yu;
    const double mixed = time_ms(9, [&] { for (int i = 0; i < 100; ++i) solver.multiply(x, y); }) / 100;
    const double k = time_ms(9, [&] { for (int i = 0; i < 100; ++i) solver.deviatoric_model().multiply(xu, yu); }) / 100;
    std::printf("\nproduct on %zu tets: mixed %.3f ms, K_mu alone %.3f ms\n", m.num_tets(), mixed, k);
  }
  if (section("frames")) {
    std::printf("\n4. Frames, cylinder %dx%dx%d, pressure +5%% a frame for 8 frames then held, warm start (iterations/ms/residual)\n", big.a, big.b, big.c);
    for (double nu : nus) frames(nu, big.a, big.b, big.c, csv.get());
  }
  return 0;
}
