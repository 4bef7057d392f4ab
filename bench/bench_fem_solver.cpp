// The speed/accuracy trade of the FEM solvers, measured in one run (each section against its
// own baseline):
//  1. warm vs cold start: iterations and time per frame with a smoothly moving probe;
//  2. iteration cap and wall-clock budget -> error against the converged (direct) solution;
//  3. tolerance -> error and time;
//  4. mesh resolution -> tip error against Timoshenko beam theory, and time (CG and direct);
//  5. linear vs corotational vs springs vs direct on one cantilever, small and large load;
//  6. CG iterations against mesh quality (worst dihedral after jitter) and against nu;
//  7. spectrum: the quality report's CG iteration estimates (formula, and Lanczos from a short
//     CG solve) against full solves on the sample meshes, unpreconditioned and Jacobi.
//   bench_fem_solver [--out DIR] [--quick] [--only warm|cap|tolerance|resolution|models|conditioning|spectrum]
//                    [--lanczos 20,40,80,160] [--meshes a.msh,b.msh]   (spectrum: default samples/*.msh)
#include <cmath>
#include <numbers>
#include <random>

#include "bench/bench_common.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "quality/conditioning.h"
#include "quality/improve.h"
#include "sim/fem/cg_spectrum.h"
#include "sim/fem/fem_simulation.h"
#include "sim/springs/spring_model.h"
#include "testing/mesh_edits.h"

using namespace incise;
using incise::testing::jitter;
using namespace incise::bench;

namespace {

MaterialTable material(double e, double nu) {
  Material m;
  m.young = e;
  m.poisson = nu;
  return MaterialTable(m);
}

// Smallest dihedral angle of the mesh [degrees].
double worst_dihedral(const TetMesh& m) {
  double worst = 180;
  for (TetId t : m.tets()) {
    const auto& v = m.tet_vertices(t);
    Vec3 p[4];
    for (int i = 0; i < 4; ++i) p[i] = m.rest(v[i]);
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        int c = -1, d = -1;
        for (int k = 0; k < 4; ++k)
          if (k != a && k != b) (c < 0 ? c : d) = k;
        const Vec3 e = (p[b] - p[a]).normalized();
        Vec3 u = p[c] - p[a], w = p[d] - p[a];
        u -= u.dot(e) * e;
        w -= w.dot(e) * e;
        const double ang = std::acos(std::clamp(u.normalized().dot(w.normalized()), -1.0, 1.0)) * 180 / std::numbers::pi;
        worst = std::min(worst, ang);
      }
  }
  return worst;
}

struct Beam {
  double len = 8, h = 1, e = 1e6, nu = 0.3;
  TetMesh mesh;
  explicit Beam(int n) : mesh(make_box(Vec3(len, h, h), {int(len) * n, n, n})) {}
  double timoshenko(double p) const {
    const double inertia = h * h * h * h / 12, area = h * h, g = e / (2 * (1 + nu));
    const double kappa = 10 * (1 + nu) / (12 + 11 * nu);
    return p * len * len * len / (3 * e * inertia) + p * len / (kappa * g * area);
  }
  void setup(FemSimulation& sim, double p) const {
    int tip = 0;
    for (VertexId v : mesh.vertices()) {
      if (mesh.rest(v).x() < 1e-9) sim.fix(v);
      if (mesh.rest(v).x() > len - 1e-9) ++tip;
    }
    for (VertexId v : mesh.vertices())
      if (mesh.rest(v).x() > len - 1e-9) sim.set_force(v, Vec3(0, 0, p / tip));
  }
  double tip(const Eigen::VectorXd& u) const {
    double s = 0;
    int n = 0;
    for (VertexId v : mesh.vertices())
      if (mesh.rest(v).x() > len - 1e-9) {
        s += u[3 * v.idx() + 2];
        ++n;
      }
    return s / n;
  }
};

double rel(const Eigen::VectorXd& a, const Eigen::VectorXd& ref) { return (a - ref).norm() / ref.norm(); }

// 7. Formula and Lanczos estimates of CG iterations against full solves, on the problem the
// quality report measures (sim/fem/cg_spectrum.h: clamped on one side, gravity-like load, nu 0.45,
// tolerance 1e-6).
void spectrum_section(const Args& args, const std::string& out, bool quick) {
  const std::string dir = std::string(INCISE_SOURCE_DIR) + "/samples/";
  std::vector<std::string> files;
  std::stringstream ss(args.get("--meshes", dir + "liver.msh," + dir + "elephant.msh"));
  for (std::string f; std::getline(ss, f, ',');) files.push_back(f);
  std::vector<int> ks;
  for (double k : args.list("--lanczos", quick ? "20,40,80" : "20,40,60,80,100,120,160")) ks.push_back(int(k));
  struct Case {
    std::string name;
    TetMesh mesh;
  };
  std::vector<Case> cases;
  for (const std::string& f : files) {
    const std::string name = std::filesystem::path(f).filename().string();
    cases.push_back({name, read_tet_mesh(f)});
    if (name == "liver.msh") {  // what `incise improve` makes of it (the CLI's defaults)
      TetMesh m = read_tet_mesh(f);
      ImproveOptions io;
      io.slide_curved = true;
      improve(m, io);
      m.discard_change();
      m.compact();
      cases.push_back({"liver improved", std::move(m)});
    }
  }
  cases.push_back({"bar 4x1x1", make_box(Vec3(4, 1, 1), {16, 4, 4})});  // slender: one soft bending mode
  for (int n : {8, 16}) {
    cases.push_back({"box " + std::to_string(n) + "^3", make_box(Vec3(1, 1, 1), {n, n, n})});
    TetMesh j = make_box(Vec3(1, 1, 1), {n, n, n});
    jitter(j, 0.45, 5);
    cases.push_back({"box " + std::to_string(n) + "^3 jitter 0.45", std::move(j)});
  }
  const double tol = 1e-6, nu = 0.45;
  Csv csv(out, "fem_spectrum.csv",
          "mesh,tets,preconditioner,lanczos_iterations,formula_iterations,lanczos_kappa,lanczos_iterations_predicted,"
          "full_iterations,predicted_over_full,estimate_ms,full_ms");
  std::printf("7. CG iterations to %g (nu %g, clamped on the low 10%% of the longest axis, gravity-like load):\n"
              "   formula (quality/conditioning.h), Lanczos estimate after k CG iterations (sim/fem/cg_spectrum.h),\n"
              "   and the full solve; ratio = estimate / full; times of the k-iteration run and of the full solve\n",
              tol, nu);
  for (const Case& c : cases) {
    SolverEstimateOptions fo;
    fo.tolerance = tol;
    fo.poisson_ratio = nu;
    const SolverEstimate formula = estimate_solver(c.mesh, fo);
    Material m;
    m.young = 1;
    m.poisson = nu;
    const double t0 = now_ms();
    const FemModel model(c.mesh, MaterialTable(m));
    const ClampedProblem problem = clamped_problem(model);
    const double model_ms = now_ms() - t0;
    std::printf("   %s: %zu tets, %zu clamped vertices, FEM model %.1f ms\n", c.name.c_str(), c.mesh.num_tets(),
                problem.fixed_vertices, model_ms);
    for (Preconditioner pc : {Preconditioner::None, Preconditioner::Jacobi}) {
      const CgSpectrumRun full = run_cg_spectrum(model, problem, pc, 100000, tol);
      std::printf("     %-7s full %6d it %8.1f ms | formula %6.0f (%5.2f)", to_string(pc), full.iterations, full.ms,
                  pc == Preconditioner::None ? std::ceil(formula.cg_iterations) : NAN,
                  pc == Preconditioner::None ? std::ceil(formula.cg_iterations) / full.iterations : NAN);
      std::printf(" | Ritz kappa of the full run %.3g\n", full.kappa);
      for (int k : ks) {
        const CgSpectrumRun est = run_cg_spectrum(model, problem, pc, k, tol);
        const double ratio = est.predicted_iterations / full.iterations;
        std::printf("       k %4d: kappa %10.4g -> %6.0f it (%5.2f), %7.1f ms (%.3f of full)", k, est.kappa,
                    std::ceil(est.predicted_iterations), ratio, est.ms, est.ms / full.ms);
        std::printf(" | plain bound %6.0f (%5.2f)\n", std::ceil(est.classic_iterations), est.classic_iterations / full.iterations);
        csv.row(c.name, c.mesh.num_tets(), to_string(pc), k, pc == Preconditioner::None ? formula.cg_iterations : NAN,
                est.kappa, est.predicted_iterations, full.iterations, ratio, est.ms, full.ms);
      }
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  Args args(argc, argv);
  const std::string out = args.get("--out", ".");
  const bool quick = args.flag("--quick");
  const std::string only = args.get("--only", "");
  auto want = [&](const char* name) { return only.empty() || only == name; };
  const int n_beam = quick ? 3 : 5;  // cells across the beam section

  // ---- 1. warm vs cold start ------------------------------------------------------------
  if (want("warm")) {
    Beam beam(n_beam);
    Csv csv(out, "fem_warm_cold.csv", "probe_step_pct,frame,cold_iterations,cold_ms,warm_iterations,warm_ms");
    std::vector<VertexId> probe;
    for (VertexId v : beam.mesh.vertices())
      if (beam.mesh.rest(v).x() > beam.len - 1e-9) probe.push_back(v);
    auto make = [&](bool warm) {
      FemSimulationOptions o;
      o.warm_start = warm;
      o.cg.tolerance = 1e-6;
      auto sim = std::make_unique<FemSimulation>(beam.mesh, material(beam.e, beam.nu), o);
      for (VertexId v : beam.mesh.vertices())
        if (beam.mesh.rest(v).x() < 1e-9) sim->fix(v);
      return sim;
    };
    const int frames = 20;
    std::printf("1. warm vs cold start (%zu tets, probe at the tip moving smoothly, tol 1e-6, %d frames)\n",
                beam.mesh.num_tets(), frames);
    for (double step_pct : {10.0, 1.0, 0.1}) {  // probe motion per frame, % of the amplitude
      auto cold = make(false), warm = make(true);
      long it_c = 0, it_w = 0;
      double ms_c = 0, ms_w = 0;
      for (int f = 0; f < frames; ++f) {
        const double z = -0.3 * (1 + f * step_pct / 100);  // starts deflected, keeps moving
        for (VertexId v : probe) {
          cold->prescribe(v, Vec3(0, 0, z));
          warm->prescribe(v, Vec3(0, 0, z));
        }
        const FrameStats c = cold->step(), w = warm->step();
        csv.row(step_pct, f, c.iterations, c.solve_ms, w.iterations, w.solve_ms);
        if (f == 0) continue;  // the first frame starts from rest for both
        it_c += c.iterations;
        it_w += w.iterations;
        ms_c += c.solve_ms;
        ms_w += w.solve_ms;
      }
      std::printf("   probe step %4.1f%%/frame: iterations per frame cold %.1f, warm %.1f (warm/cold %.2f); ms cold %.2f, "
                  "warm %.2f (%.2f)\n",
                  step_pct, double(it_c) / (frames - 1), double(it_w) / (frames - 1), double(it_w) / double(it_c),
                  ms_c / (frames - 1), ms_w / (frames - 1), ms_w / ms_c);
    }
  }

  // Reference problem for sections 2-3: the beam with a tip load, solved exactly.
  Beam beam(n_beam);
  FemSimulationOptions dopt;
  dopt.method = SolverMethod::Direct;
  FemSimulation direct(beam.mesh, material(beam.e, beam.nu), dopt);
  beam.setup(direct, -1);
  const double t_direct0 = now_ms();
  direct.step();
  const double direct_ms = now_ms() - t_direct0;
  const Eigen::VectorXd ref = direct.displacement();

  // ---- 2. iteration cap and budget -> error ------------------------------------------------
  if (want("cap")) {
    Csv csv(out, "fem_cap_error.csv", "max_iterations,iterations,relative_residual,relative_error,solve_ms");
    std::printf("2. iteration cap -> error against the direct solution (%zu tets, cold start, one frame)\n",
                beam.mesh.num_tets());
    std::printf("   %8s %10s %12s %12s %9s\n", "cap", "iters", "residual", "error", "ms");
    for (int cap : {10, 20, 50, 100, 200, 400, 800, 1600, 3200}) {
      FemSimulationOptions o;
      o.cg.max_iterations = cap;
      o.cg.tolerance = 1e-12;
      FemSimulation sim(beam.mesh, material(beam.e, beam.nu), o);
      beam.setup(sim, -1);
      const FrameStats st = sim.step();
      const double err = rel(sim.displacement(), ref);
      csv.row(cap, st.iterations, st.relative_residual, err, st.solve_ms);
      std::printf("   %8d %10d %12.3e %12.3e %9.2f\n", cap, st.iterations, st.relative_residual, err, st.solve_ms);
    }
    Csv csv2(out, "fem_budget_error.csv", "budget_ms,frame,iterations,relative_error,budget_exhausted");
    std::printf("   budget per frame -> error after frames 1, 2, 5, 10 (static load: later frames continue)\n");
    for (double budget : {2.0, 10.0, 50.0, 100.0}) {
      FemSimulationOptions o;
      o.cg.budget_ms = budget;
      o.cg.tolerance = 1e-10;
      FemSimulation sim(beam.mesh, material(beam.e, beam.nu), o);
      beam.setup(sim, -1);
      std::printf("   budget %5.1f ms:", budget);
      for (int f = 1; f <= 10; ++f) {
        const FrameStats st = sim.step();
        const double err = rel(sim.displacement(), ref);
        csv2.row(budget, f, st.iterations, err, st.budget_exhausted ? 1 : 0);
        if (f == 1 || f == 2 || f == 5 || f == 10) std::printf("  f%d %.2e", f, err);
      }
      std::printf("\n");
    }
  }

  // ---- 3. tolerance -> error --------------------------------------------------------------
  if (want("tolerance")) {
    Csv csv(out, "fem_tolerance_error.csv", "tolerance,iterations,relative_error,solve_ms,direct_ms");
    std::printf("3. tolerance -> error (direct solve: %.1f ms incl. factorization)\n", direct_ms);
    std::printf("   %10s %8s %12s %9s %10s\n", "tol", "iters", "error", "ms", "ms/direct");
    for (double tol : {1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-8, 1e-10}) {
      FemSimulationOptions o;
      o.cg.tolerance = tol;
      FemSimulation sim(beam.mesh, material(beam.e, beam.nu), o);
      beam.setup(sim, -1);
      const FrameStats st = sim.step();
      const double err = rel(sim.displacement(), ref);
      csv.row(tol, st.iterations, err, st.solve_ms, direct_ms);
      std::printf("   %10.0e %8d %12.3e %9.2f %10.2f\n", tol, st.iterations, err, st.solve_ms, st.solve_ms / direct_ms);
    }
  }

  // ---- 4. resolution -> error against beam theory, and time ---------------------------------
  if (want("resolution")) {
    Csv csv(out, "fem_resolution.csv", "n,tets,tip_error_vs_timoshenko,cg_iterations,cg_ms,direct_ms");
    std::printf("4. resolution -> tip error against Timoshenko, time (CG tol 1e-8 cold, direct)\n");
    std::printf("   %6s %8s %10s %8s %10s %10s\n", "n", "tets", "error", "iters", "cg ms", "direct ms");
    for (int n : quick ? std::vector<int>{1, 2, 3, 4} : std::vector<int>{1, 2, 3, 4, 6, 8}) {
      Beam b(n);
      FemSimulationOptions o;
      o.cg.tolerance = 1e-8;
      FemSimulation cg(b.mesh, material(b.e, b.nu), o);
      b.setup(cg, -1);
      const FrameStats st = cg.step();
      FemSimulation d(b.mesh, material(b.e, b.nu), dopt);
      b.setup(d, -1);
      const double t0 = now_ms();
      d.step();
      const double dms = now_ms() - t0;
      const double err = std::abs(b.tip(cg.displacement()) - b.timoshenko(-1)) / std::abs(b.timoshenko(-1));
      csv.row(n, b.mesh.num_tets(), err, st.iterations, st.solve_ms, dms);
      std::printf("   %6d %8zu %10.4f %8d %10.1f %10.1f\n", n, b.mesh.num_tets(), err, st.iterations, st.solve_ms, dms);
    }
  }

  // ---- 5. linear vs corotational vs springs vs direct ----------------------------------------
  if (want("models")) {
    Csv csv(out, "fem_models.csv", "load,model,tip_deflection,relative_to_linear_direct,ms");
    std::printf("5. models on the cantilever (%zu tets), tip deflection / linear direct, time\n", beam.mesh.num_tets());
    for (double load : {-1.0, -300.0}) {
      FemSimulation lin_d(beam.mesh, material(beam.e, beam.nu), dopt);
      beam.setup(lin_d, load);
      double t0 = now_ms();
      lin_d.step();
      const double ref_tip = beam.tip(lin_d.displacement());
      auto report = [&](const char* name, double tip, double ms) {
        csv.row(load, name, tip, tip / ref_tip, ms);
        std::printf("   load %6.1f  %-26s tip %10.5f  ratio %6.3f  %9.1f ms\n", load, name, tip, tip / ref_tip, ms);
      };
      report("fem-linear direct", ref_tip, now_ms() - t0);
      FemSimulationOptions o;
      o.cg.tolerance = 1e-8;
      FemSimulation lin(beam.mesh, material(beam.e, beam.nu), o);
      beam.setup(lin, load);
      t0 = now_ms();
      lin.step();
      report("fem-linear cg", beam.tip(lin.displacement()), now_ms() - t0);
      o.kind = FemKind::Corotational;
      FemSimulation cor(beam.mesh, material(beam.e, beam.nu), o);
      beam.setup(cor, load);
      t0 = now_ms();
      Eigen::VectorXd prev;
      int frames = 0;
      do {  // re-linearize until the frame-to-frame change is small
        prev = cor.displacement();
        cor.step();
        ++frames;
      } while (frames < 60 && (cor.displacement() - prev).norm() > 1e-6 * cor.displacement().norm());
      report(("fem-corotational cg (" + std::to_string(frames) + " fr)").c_str(), beam.tip(cor.displacement()), now_ms() - t0);
      // Springs: damped implicit Euler to rest.
      SpringOptions so;
      so.damping = 1;  // about critical for the first bending mode (omega ~ 0.5 rad/s)
      so.compute_energy = false;
      SpringModel springs(beam.mesh, material(beam.e, beam.nu), so);
      int tipn = 0;
      for (VertexId v : beam.mesh.vertices()) tipn += beam.mesh.rest(v).x() > beam.len - 1e-9;
      for (VertexId v : beam.mesh.vertices()) {
        if (beam.mesh.rest(v).x() < 1e-9) springs.set_fixed(v, true);
        if (beam.mesh.rest(v).x() > beam.len - 1e-9) springs.set_external_force(v, Vec3(0, 0, load / tipn));
      }
      t0 = now_ms();
      Eigen::VectorXd u = Eigen::VectorXd::Zero(Eigen::Index(3 * beam.mesh.vertex_capacity()));
      for (int s = 0; s < 60; ++s) springs.step(5.0, Integrator::ImplicitEuler);  // relax to rest
      for (VertexId v : beam.mesh.vertices()) u.segment<3>(3 * v.idx()) = springs.positions()[v.idx()] - beam.mesh.rest(v);
      report("springs implicit (60 st)", beam.tip(u), now_ms() - t0);
    }
  }

  // ---- 6. CG iterations against mesh quality and nu ------------------------------------------
  if (want("conditioning")) {
    Csv csv(out, "fem_conditioning.csv", "series,parameter,worst_dihedral_deg,iterations,solve_ms");
    const int n = quick ? 8 : 12;
    std::printf("6. CG iterations (tol 1e-8, Jacobi) on a %d^3 box fixed at the bottom under gravity\n", n);
    auto run = [&](const TetMesh& m, double nu) {
      FemSimulationOptions o;
      o.cg.tolerance = 1e-8;
      o.cg.max_iterations = 100000;
      o.gravity = Vec3(0, 0, -9.81);
      FemSimulation sim(m, material(1e5, nu), o);
      for (VertexId v : m.vertices())
        if (m.rest(v).z() < 1e-9) sim.fix(v);
      return sim.step();
    };
    std::printf("   jitter  worst dihedral  iterations\n");
    for (double j : {0.0, 0.1, 0.2, 0.3, 0.4, 0.45, 0.49}) {
      TetMesh m = make_box(Vec3(1, 1, 1), {n, n, n});
      jitter(m, j, 5);
      const double wd = worst_dihedral(m);
      const FrameStats st = run(m, 0.3);
      csv.row("quality", j, wd, st.iterations, st.solve_ms);
      std::printf("   %6.2f  %10.2f deg  %10d\n", j, wd, st.iterations);
    }
    std::printf("   nu       iterations\n");
    TetMesh m = make_box(Vec3(1, 1, 1), {n, n, n});
    const double wd = worst_dihedral(m);
    for (double nu : {0.0, 0.3, 0.45, 0.49, 0.499, 0.4999}) {
      const FrameStats st = run(m, nu);
      csv.row("poisson", nu, wd, st.iterations, st.solve_ms);
      std::printf("   %-8g %10d\n", nu, st.iterations);
    }
  }
  if (want("spectrum")) spectrum_section(args, out, quick);
  std::printf("CSV files in %s; plot: /usr/bin/python3 bench/plot_fem.py %s\n", out.c_str(), out.c_str());
  return 0;
}
