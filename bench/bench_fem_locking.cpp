// Volumetric locking of linear tets, and what the nodal-averaged and edge-smoothed formulations
// (sim/fem/formulation.h) do about it and cost:
//  1. accuracy: cantilever 10 x 1 x 1 (E = 1e6, tip shear load 1, clamped), tip deflection
//     against Timoshenko beam theory, per Poisson's ratio, mesh and formulation. Solved by CG
//     with the (exact, CHOLMOD) Cholesky preconditioner to 1e-12, which equals the direct solve
//     (tests/sim/test_nodal_averaged.cpp) and is much faster than the SimplicialLDLT direct
//     solver on the nodal-averaged 2-ring pattern (80x8x8: ~25 s a solve; --direct uses it);
//  2. solver cost: CG iterations and ms per static solve (cold start, preconditioner set up by a
//     first frame) per Poisson's ratio, formulation and preconditioner.
//   bench_fem_locking [--out DIR] [--quick] [--only accuracy|cg] [--nu 0.3,0.45,0.49,0.4999]
//                     [--meshes 20,40,80,120] [--cg-meshes 40,80] [--direct] [--split kuhn|mirrored]
//   --split: how make_box splits each cube (mesh/generate.h BoxSplit).
#include <cmath>
#include <cstdio>
#include <iterator>

#include "bench/bench_common.h"
#include "mesh/generate.h"
#include "sim/fem/fem_simulation.h"

using namespace incise;
using namespace incise::bench;

namespace {

constexpr double kLen = 10, kH = 1, kE = 1e6, kLoad = -1;

MaterialTable material(double nu) {
  Material m;
  m.young = kE;
  m.poisson = nu;
  return MaterialTable(m);
}

double timoshenko(double nu) {
  const double inertia = kH * kH * kH * kH / 12, area = kH * kH, g = kE / (2 * (1 + nu));
  const double shear = 10 * (1 + nu) / (12 + 11 * nu);  // Cowper, rectangular section
  return kLoad * kLen * kLen * kLen / (3 * kE * inertia) + kLoad * kLen / (shear * g * area);
}

// The cantilever's constraints and loads (consistent nodal forces of a uniform shear traction
// on the tip face).
void load(const TetMesh& m, FemSimulation& sim) {
  for (VertexId v : m.vertices())
    if (m.rest(v).x() < 1e-9) sim.fix(v);
  const double traction = kLoad / (kH * kH);
  for (const auto& f : m.boundary_faces()) {
    bool tip = true;
    for (VertexId v : f.vertices) tip = tip && m.rest(v).x() > kLen - 1e-9;
    if (!tip) continue;
    const Vec3 a = m.rest(f.vertices[0]), b = m.rest(f.vertices[1]), c = m.rest(f.vertices[2]);
    const double area = 0.5 * (b - a).cross(c - a).norm();
    for (VertexId v : f.vertices) sim.add_force(v, Vec3(0, 0, traction * area / 3));
  }
}

double tip(const TetMesh& m, const Eigen::VectorXd& u) {
  double s = 0;
  int n = 0;
  for (VertexId v : m.vertices())
    if (m.rest(v).x() > kLen - 1e-9) {
      s += u[3 * v.idx() + 2];
      ++n;
    }
  return s / n;
}

BoxSplit g_split = BoxSplit::Kuhn;  // --split

TetMesh beam(int nx) {
  return make_box(Vec3(kLen, kH, kH), {nx, std::max(1, nx / 10), std::max(1, nx / 10)}, 1, g_split);
}

const Formulation kForms[] = {Formulation::Standard, Formulation::NodalAveraged, Formulation::EdgeSmoothed};

// The reference solution of the cantilever: see the header comment.
FemSimulationOptions reference_options(Formulation f, bool direct) {
  FemSimulationOptions opt;
  opt.formulation = f;
  opt.method = direct ? SolverMethod::Direct : SolverMethod::Cg;
  opt.cg.tolerance = 1e-12;
  opt.cg.max_iterations = 1000;
  opt.cg.preconditioner = Preconditioner::Cholesky;
  opt.cholesky.background = false;
  opt.warm_start = false;
  opt.predict = false;
  return opt;
}

void accuracy(const Args& args, const std::vector<double>& nus, Csv& csv) {
  const std::vector<double> meshes = args.list("--meshes", args.flag("--quick") ? "20,40" : "20,40,80,120");
  const bool direct = args.flag("--direct");
  std::printf("\n== cantilever 10x1x1, E=1e6, tip load 1: tip deflection error against Timoshenko (%s)\n",
              direct ? "direct solve" : "CG + exact Cholesky to 1e-12");
  std::printf("%-10s %8s %9s %16s %16s %16s %10s %10s\n", "mesh", "tets", "nu", "standard", "nodal-averaged",
              "edge-smoothed", "ms (n-a)", "ms (e-s)");
  for (double nxd : meshes) {
    const int nx = int(nxd);
    const TetMesh m = beam(nx);
    for (double nu : nus) {
      constexpr int kCount = int(std::size(kForms));
      double err[kCount], ms[kCount];
      for (int k = 0; k < kCount; ++k) {
        const FemSimulationOptions opt = reference_options(kForms[k], direct);
        const double t0 = now_ms();
        FemSimulation sim(m, material(nu), opt);
        load(m, sim);
        sim.step();
        ms[k] = now_ms() - t0;
        err[k] = tip(m, sim.displacement()) / timoshenko(nu) - 1;
        csv.row("accuracy", formulation_name(kForms[k]), nx, m.num_tets(), nu, direct ? "direct" : "cg-cholesky", err[k],
                0, ms[k]);
      }
      char name[32];
      std::snprintf(name, sizeof name, "%dx%dx%d", nx, std::max(1, nx / 10), std::max(1, nx / 10));
      std::printf("%-10s %8zu %9.4f %15.2f%% %15.2f%% %15.2f%% %10.1f %10.1f\n", name, m.num_tets(), nu, 100 * err[0],
                  100 * err[1], 100 * err[2], ms[1], ms[2]);
    }
  }
}

void cg_cost(const Args& args, const std::vector<double>& nus, Csv& csv) {
  const std::vector<double> meshes = args.list("--cg-meshes", args.flag("--quick") ? "40" : "40,80");
  const Preconditioner pcs[] = {Preconditioner::Jacobi, Preconditioner::BlockJacobi, Preconditioner::Cholesky,
                                Preconditioner::Amg};
  std::printf("\n== CG (tolerance 1e-8, cold start) per static solve: iterations / ms; setup = first frame ms "
              "(factor, multigrid build)\n");
  for (double nxd : meshes) {
    const int nx = int(nxd);
    const TetMesh m = beam(nx);
    std::printf("-- %dx%dx%d (%zu tets)\n", nx, nx / 10, nx / 10, m.num_tets());
    // The product alone (what an iteration adds to the preconditioner), linear elements.
    for (Formulation f : kForms) {
      const FemModel model(m, material(0.49), FemKind::Linear, f);
      Eigen::VectorXd x = Eigen::VectorXd::Random(model.rows()), y;
      const double ms = time_ms(9, [&] {
        for (int k = 0; k < 20; ++k) model.multiply(x, y);
      }) / 20;
      std::printf("K x %-15s %.3f ms, K has %ld nonzeros\n", std::string(formulation_name(f)).c_str(), ms,
                  long(model.assemble().nonZeros()));
      csv.row("product", formulation_name(f), nx, m.num_tets(), 0.49, "multiply", 0, 0, ms);
    }
    std::printf("%-15s %-13s %9s %8s %9s %10s %11s\n", "formulation", "precond", "nu", "iters", "ms/solve", "setup ms",
                "err/ref");
    for (Formulation f : kForms)
      for (Preconditioner pc : pcs)
        for (double nu : nus) {
          FemSimulation direct(m, material(nu), reference_options(f, false));
          load(m, direct);
          direct.step();
          FemSimulationOptions opt;
          opt.formulation = f;
          opt.cg.tolerance = 1e-8;
          opt.cg.max_iterations = 50000;
          opt.cg.preconditioner = pc;
          opt.cholesky.background = false;
          opt.warm_start = false;
          opt.predict = false;
          FemSimulation sim(m, material(nu), opt);
          load(m, sim);
          const double t0 = now_ms();
          sim.step();  // sets the preconditioner up
          const double setup = now_ms() - t0;
          sim.reset_state();
          const FrameStats st = sim.step();
          const double err = (sim.displacement() - direct.displacement()).norm() / direct.displacement().norm();
          std::printf("%-15s %-13s %9.4f %8d %9.1f %10.1f %11.1e%s\n", std::string(formulation_name(f)).c_str(),
                      to_string(pc), nu, st.iterations, st.solve_ms, setup, err,
                      st.info == SolveInfo::Success ? "" : " (not converged)");
          csv.row("cg", formulation_name(f), nx, m.num_tets(), nu, to_string(pc), err, st.iterations, st.solve_ms);
        }
  }
}

}  // namespace

int main(int argc, char** argv) {
  const Args args(argc, argv);
  const std::vector<double> nus = args.list("--nu", "0.3,0.45,0.49,0.4999");
  const std::string only = args.get("--only", "");
  const std::string split = args.get("--split", "kuhn");
  if (split != "kuhn" && split != "mirrored") {
    std::fprintf(stderr, "bench_fem_locking: --split: expected kuhn or mirrored, got %s\n", split.c_str());
    return 1;
  }
  if (split == "mirrored") g_split = BoxSplit::Mirrored;
  Csv csv(args.get("--out", "bench_out"), "fem_locking.csv", "section,formulation,nx,tets,nu,solver,error,iterations,ms");
  if (only.empty() || only == "accuracy") accuracy(args, nus, csv);
  if (only.empty() || only == "cg") cg_cost(args, nus, csv);
  std::printf("\nCSV: %s\n", csv.path().c_str());
  return 0;
}
