// Preconditioners, budgets and warm start, each against a baseline measured in the same run
// (--only SECTION runs one):
//  beam:      iterations and time per frame on the sample beam scene, for Jacobi (baseline),
//             block-Jacobi, Cholesky (the scene default) and the aggregation multigrid (amg);
//  organ:     the same on an organ (--organ), uncut and cut mid-run;
//  budget:    budgeted convergence on a cantilever: relative residual against frames at several
//             budgets, resuming CG (now) against restarting it every frame (before);
//  holds:     a small budget on the 80x8x8 cantilever: the share of frames within twice it
//             (the budget and the bound are in section_budget_holds);
//  cut-scene: the organ cut scene (--organ) per preconditioner and policy: frame, cut, setup,
//             solve, iterations, residuals;
//  amg-build: the multigrid's build phases and applications on the organ;
//  scaling:   each parallel pass and the organ cut frame on 1, 2, 4, ... threads, and the serial
//             share (issue 37; docs/solver.md#what-each-core-buys); only with --only;
//  warm:      warm start on a probe moving steadily over 40 frames: iterations of the last
//             solution and of the prediction against a cold start;
//  rotated:   a corotational beam bent far with a stale Cholesky factor, rotated against as is;
//  poisson:   iterations against Poisson's ratio up to 0.4999 for each preconditioner;
//  with --size-tets N: Jacobi against Cholesky on a large model (first-frame wait, memory).
//   bench_fem_precond [--organ MESH] [--organ2 MESH] [--scaling-box-tets N] [--beam SCENE]
//                     [--budget-tets 30000] [--only SECTION] [--size-tets N] [--out DIR]
#include <sys/resource.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <thread>
#include <fstream>

#include "bench/bench_common.h"
#include "mesh/generate.h"
#include "mesh/rest_bounds.h"
#include "mesh/io/tet_io.h"
#include <tbb/global_control.h>

#include "sim/fem/aggregation_amg.h"
#include "sim/fem/async_cholesky.h"
#include "sim/linalg/cg_solver.h"
#include "sim/linalg/preconditioner.h"
#include "sim/fem/fem_simulation.h"
#include "scene/run_scene.h"
#include "testing/mesh_edits.h"

using namespace incise;
using namespace incise::bench;

namespace {

const Preconditioner kPcs[] = {Preconditioner::Jacobi, Preconditioner::BlockJacobi, Preconditioner::Cholesky,
                               Preconditioner::Amg};

MaterialTable material(double e, double nu) {
  Material m;
  m.young = e;
  m.poisson = nu;
  return MaterialTable(m);
}

struct Box {
  Vec3 lo, hi;
  explicit Box(const TetMesh& m) {
    const RestBounds b = rest_bounds(m);
    lo = b.lo;
    hi = b.hi;
  }
  Vec3 size() const { return hi - lo; }
};

// An organ scenario: bottom 15% (z) fixed, a probe on the top 5% near the centre pushes down
// 5% of the height over 30 frames, then holds; corotational, soft tissue. Optionally a crack
// through the middle at `cut_frame`, deepened at the next two frames.
struct OrganRun {
  double iterations_per_frame = 0, ms_per_frame = 0;
  int not_converged = 0, after_cut_max_iterations = 0;
  Eigen::VectorXd u;
};
OrganRun run_organ(const TetMesh& organ, Preconditioner pc, int frames, int cut_frame) {
  TetMesh m = organ;
  m.discard_change();
  const Box b(m);
  const Vec3 c = 0.5 * (b.lo + b.hi), s = b.size();
  FemSimulationOptions opt;
  opt.kind = FemKind::Corotational;
  opt.cg.tolerance = 1e-6;
  opt.cg.max_iterations = 20000;
  opt.cg.preconditioner = pc;
  FemSimulation sim(m, material(1e4, 0.45), opt);
  std::vector<VertexId> probe;
  for (VertexId v : m.vertices()) {
    const Vec3 p = m.rest(v);
    if (p.z() < b.lo.z() + 0.15 * s.z()) sim.fix(v);
    else if (p.z() > b.hi.z() - 0.25 * s.z() && std::abs(p.x() - c.x()) < 0.12 * s.x() && std::abs(p.y() - c.y()) < 0.12 * s.y())
      probe.push_back(v);
  }
  // The probe: the highest vertices of that column.
  std::sort(probe.begin(), probe.end(), [&](VertexId a, VertexId d) { return m.rest(a).z() > m.rest(d).z(); });
  probe.resize(std::max<std::size_t>(3, probe.size() / 4));
  OrganRun r;
  for (int f = 0; f < frames; ++f) {
    if (cut_frame >= 0 && f >= cut_frame && f < cut_frame + 3) {
      incise::testing::crack(m, 0, c.x(), 2, b.hi.z() - (0.2 + 0.15 * (f - cut_frame)) * s.z());
      sim.apply(m.take_change());
    }
    const double k = std::min(1.0, double(f + 1) / 30);
    for (VertexId v : probe) sim.prescribe(v, Vec3(0, 0, -0.05 * s.z() * k));
    const FrameStats& st = sim.step();
    r.iterations_per_frame += st.iterations;
    r.ms_per_frame += st.frame_ms;
    r.not_converged += st.info != SolveInfo::Success;
    if (cut_frame >= 0 && f >= cut_frame) r.after_cut_max_iterations = std::max(r.after_cut_max_iterations, st.iterations);
  }
  r.iterations_per_frame /= frames;
  r.ms_per_frame /= frames;
  r.u = sim.displacement();
  return r;
}

void section_organ(const std::string& name, const TetMesh& m, int cut_frame, Csv& csv) {
  std::printf("\n%s: %zu tets, corotational, nu 0.45, tolerance 1e-6, 40 frames%s\n", name.c_str(), m.num_tets(),
              cut_frame >= 0 ? ", cut at frames 10-12" : "");
  std::printf("  %-13s %10s %10s %10s %10s %12s %14s\n", "preconditioner", "it/frame", "ms/frame", "it ratio", "ms ratio",
              "unconverged", "max it after cut");
  OrganRun base;
  for (Preconditioner pc : kPcs) {
    const OrganRun r = run_organ(m, pc, 40, cut_frame);
    if (pc == Preconditioner::Jacobi) base = r;
    const double diff = (r.u - base.u).norm() / std::max(1e-300, base.u.norm());
    std::printf("  %-13s %10.1f %10.2f %10.3f %10.3f %12d %14d   (answer vs Jacobi: %.1e)\n", to_string(pc),
                r.iterations_per_frame, r.ms_per_frame, r.iterations_per_frame / base.iterations_per_frame,
                r.ms_per_frame / base.ms_per_frame, r.not_converged, r.after_cut_max_iterations, diff);
    csv.row(name, to_string(pc), m.num_tets(), r.iterations_per_frame, r.ms_per_frame,
            r.iterations_per_frame / base.iterations_per_frame, r.ms_per_frame / base.ms_per_frame, r.not_converged,
            r.after_cut_max_iterations, diff);
  }
}

void section_beam_scene(const std::string& path, Csv& csv) {
  Scene scene = load_scene(path);
  std::printf("\nsample scene %s (its own settings but the preconditioner)\n", path.c_str());
  std::printf("  %-13s %10s %10s %10s %10s\n", "preconditioner", "it/frame", "ms/frame", "it ratio", "ms ratio");
  double base_it = 0, base_ms = 0;
  for (Preconditioner pc : kPcs) {
    scene.cg.preconditioner = pc;
    double it = 0, ms = 0;
    int frames = 0;
    SceneRunOptions ro;
    ro.on_frame = [&](int, const Eigen::VectorXd&, const FrameStats& st) {
      it += st.iterations;
      ms += st.frame_ms;
      ++frames;
    };
    run_scene(scene, ro);
    it /= frames;
    ms /= frames;
    if (pc == Preconditioner::Jacobi) base_it = it, base_ms = ms;
    std::printf("  %-13s %10.1f %10.2f %10.3f %10.3f\n", to_string(pc), it, ms, it / base_it, ms / base_ms);
    csv.row("beam-scene", to_string(pc), 0, it, ms, it / base_it, ms / base_ms, 0, 0, 0);
  }
}

// A cantilever of about `tets` tets, fixed at x = 0, a traction on its top.
struct Cantilever {
  TetMesh mesh;
  explicit Cantilever(double tets) {
    const int n = std::max(2, int(std::lround(std::cbrt(tets / (6.0 * 8)))));
    mesh = make_box(Vec3(8, 1, 1), {8 * n, n, n});
  }
  explicit Cantilever(std::array<int, 3> cells) { mesh = make_box(Vec3(10, 1, 1), cells); }
  void setup(FemSimulation& sim) const {
    for (VertexId v : mesh.vertices()) {
      if (mesh.rest(v).x() < 1e-9) sim.fix(v);
      if (mesh.rest(v).z() > 1 - 1e-9) sim.set_force(v, Vec3(0, 0, -1));
    }
  }
};

void section_budget(double tets, Csv& csv) {
  Cantilever c(tets);
  FemSimulationOptions dopt;
  dopt.method = SolverMethod::Direct;
  FemSimulation direct(c.mesh, material(1e5, 0.3), dopt);
  c.setup(direct);
  direct.step();
  const Eigen::VectorXd ref = direct.displacement();
  std::printf("\nbudgeted frames on an unchanged problem: cantilever %zu tets, linear, tolerance 1e-8; error "
              "||u - u*|| / ||u*|| (u*: direct) and relative residual after N frames\n",
              c.mesh.num_tets());
  std::printf("  %-13s %6s %8s %18s %18s %18s %18s %10s\n", "preconditioner", "budget", "mode", "frame 1 err/res",
              "frame 10", "frame 30", "frame 100", "converged@");
  for (Preconditioner pc : {Preconditioner::Jacobi, Preconditioner::BlockJacobi, Preconditioner::Cholesky,
                            Preconditioner::Amg})
    for (double budget : {2.0, 10.0})
      for (bool resume : {false, true}) {
        FemSimulationOptions opt;
        opt.cg.tolerance = 1e-8;
        opt.cg.budget_ms = budget;
        opt.cg.preconditioner = pc;
        opt.cg.max_iterations = 100000;
        FemSimulation sim(c.mesh, material(1e5, 0.3), opt);
        c.setup(sim);
        double err[4] = {0, 0, 0, 0}, res[4] = {0, 0, 0, 0};
        int converged = -1;
        for (int f = 1; f <= 100; ++f) {
          if (!resume) sim.cg().invalidate();  // the old behaviour: every frame restarts
          const FrameStats& st = sim.step();
          if (converged < 0 && st.info == SolveInfo::Success) converged = f;
          const int slot = f == 1 ? 0 : f == 10 ? 1 : f == 30 ? 2 : f == 100 ? 3 : -1;
          if (slot >= 0) {
            err[slot] = (sim.displacement() - ref).norm() / ref.norm();
            res[slot] = st.relative_residual;
          }
        }
        std::printf("  %-13s %6.0f %8s", to_string(pc), budget, resume ? "resume" : "restart");
        for (int k = 0; k < 4; ++k) std::printf("  %8.1e/%8.1e", err[k], res[k]);
        std::printf(" %10d\n", converged);
        csv.row("budget", to_string(pc), c.mesh.num_tets(), budget, resume ? "resume" : "restart", err[1], err[2], err[3],
                res[3], converged);
      }
}

// Does a 2 ms budget hold with the default settings? The 80x8x8 cantilever (30,720 tets) under
// a top load that changes every frame, 100 frames: frame time (the whole step()) against the
// goal of 2 x 1.5 + 1 ms, with the default preconditioner (Cholesky, whose application alone
// takes several budgets: the budget makes CG use its cheaper block-Jacobi) and block-Jacobi,
// and the same runs without a budget as the baseline.
void section_budget_holds(Csv& csv) {
  Cantilever c({80, 8, 8});
  const double budget = 2.0, goal = 2 * 1.5 + 1;
  std::printf("\nbudget %.0f ms on the 80x8x8 cantilever (%zu tets), load changing every frame, 100 frames, "
              "tolerance 1e-8: frame ms (whole step) median / p90 / max, share of frames within %.0f ms, frames "
              "on the cheaper preconditioner, setup (before the first solve) and solve ms median/max, residual at the end\n",
              budget, c.mesh.num_tets(), goal);
  std::printf("  %-13s %7s %8s %8s %8s %9s %8s %13s %13s %10s %12s\n", "preconditioner", "budget", "median", "p90", "max",
              "within", "cheaper", "setup med/max", "solve med/p90", "residual", "it med/max");
  // -1: the Cholesky factor with block-Jacobi while settling (settle_with_amg off, the default before).
  for (int pci : {int(Preconditioner::Cholesky), -1, int(Preconditioner::BlockJacobi), int(Preconditioner::Amg)})
    for (double b : {0.0, budget}) {
      const Preconditioner pc = pci < 0 ? Preconditioner::Cholesky : Preconditioner(pci);
      FemSimulationOptions opt;  // the defaults, but the preconditioner and the budget
      opt.cg.preconditioner = pc;
      opt.cg.budget_ms = b;
      if (pci < 0) opt.cholesky.settle_with_amg = false;
      FemSimulation sim(c.mesh, material(1e5, 0.3), opt);
      c.setup(sim);
      std::vector<double> ms, setup, solve;
      int within = 0, cheaper = 0;
      double res = 0;
      std::vector<double> its;
      for (int f = 0; f < 100; ++f) {
        const double load = 1 + 0.5 * std::sin(0.2 * f);
        for (VertexId v : c.mesh.vertices())
          if (c.mesh.rest(v).z() > 1 - 1e-9) sim.set_force(v, Vec3(0, 0, -load));
        const FrameStats& st = sim.step();
        ms.push_back(st.frame_ms);
        within += st.frame_ms <= goal;
        cheaper += st.cheaper_preconditioner;
        setup.push_back(st.setup_ms);
        solve.push_back(st.solve_ms);
        res = st.relative_residual;
        its.push_back(st.iterations);
      }
      std::vector<double> sorted = ms;
      std::sort(sorted.begin(), sorted.end());
      std::sort(setup.begin(), setup.end());
      std::sort(solve.begin(), solve.end());
      std::sort(its.begin(), its.end());
      const std::string name = pci < 0 ? "cholesky+bj" : to_string(pc);
      std::printf("  %-13s %7.0f %8.2f %8.2f %8.2f %8d%% %8d %6.2f/%6.2f %6.2f/%6.2f %10.1e %5.0f/%-6.0f\n", name.c_str(), b,
                  sorted[50], sorted[90], sorted[99], within, cheaper, setup[50], setup[99], solve[50], solve[90], res, its[50], its[99]);
      if (sim.cholesky()) std::printf("    factorizations adopted: %d\n", sim.cholesky()->factorizations());
      csv.row("budget-holds", name, c.mesh.num_tets(), b, "", sorted[50], sorted[90], sorted[99], within, cheaper);
    }
}

// The organ cut scene of the solver issue, through the scene runner as `incise simulate` runs
// it: corotational soft tissue held at the bottom 15%, a probe beside the centre pressing 5% of
// the height over 60 frames, and a blade sweeping down through the middle (65% of the height)
// over frames 10-50, one step before each frame; CG to 1e-4. Per preconditioner and policy,
// over the frames the blade moves (10-50): the whole frame (cut + step) median / p95 / max, and
// its parts (cut, setup = rotations and right-hand side, solve), CG iterations, the worst
// residual. "settle": block-Jacobi while the blade moves, a factor once the topology settled.
// The largest face-connected part of m, written to `path` (imaged organs carry specks).
TetMesh largest_part(const TetMesh& m) {
  std::vector<int> part(m.tet_capacity(), -1);
  std::vector<std::size_t> size;
  for (TetId t : m.tets()) {
    if (part[t.idx()] >= 0) continue;
    const int id = int(size.size());
    size.push_back(0);
    std::vector<TetId> stack{t};
    part[t.idx()] = id;
    while (!stack.empty()) {
      const TetId u = stack.back();
      stack.pop_back();
      ++size.back();
      for (int f = 0; f < 4; ++f) {
        const TetId n = m.neighbor(u, f);
        if (n.is_valid() && part[n.idx()] < 0) {
          part[n.idx()] = id;
          stack.push_back(n);
        }
      }
    }
  }
  const int keep = int(std::max_element(size.begin(), size.end()) - size.begin());
  TetMesh out = m;
  for (TetId t : m.tets())
    if (part[t.idx()] != keep) out.remove_tet(t);
  out.compact();
  return out;
}

// The organ cut scene: held at its base, a probe pressing its top over 60 frames, a blade
// through its middle over frames 10-50, corotational, tolerance 1e-4 (the issue 37 scene).
Scene organ_cut_scene(const TetMesh& organ, const std::string& organ_path) {
  const Box b(organ);
  const Vec3 c = 0.5 * (b.lo + b.hi), s = b.size();
  Scene scene;
  scene.path = organ_path + " (cut scene)";
  scene.mesh_file = std::filesystem::absolute(organ_path).string();
  scene.model = SceneModel::FemCorotational;
  Material tissue;
  tissue.young = 5e3;
  tissue.poisson = 0.4;
  scene.materials = MaterialTable(tissue);
  scene.fixed.push_back(SceneFixed{SceneBox{b.lo - 0.01 * s, Vec3(b.hi.x(), b.hi.y(), b.lo.z() + 0.15 * s.z()) + 0.01 * s}});
  SceneLoad probe;
  probe.kind = SceneLoad::Kind::Probe;
  probe.key = "loads[0]";
  // The probe sits on the highest surface point near (centre + 20% x): organs are not boxes.
  Vec3 pc(c.x() + 0.2 * s.x(), c.y(), b.lo.z());
  for (VertexId v : organ.vertices()) {
    const Vec3 p = organ.rest(v);
    if (std::abs(p.x() - c.x() - 0.2 * s.x()) < 0.1 * s.x() && std::abs(p.y() - c.y()) < 0.1 * s.y() && p.z() > pc.z())
      pc = p;
  }
  probe.box = SceneBox{pc - Vec3(0.08 * s.x(), 0.08 * s.y(), 0.05 * s.z()), pc + Vec3(0.08 * s.x(), 0.08 * s.y(), 0.01 * s.z())};
  probe.value = Vec3(0, 0, -0.05 * s.z());
  probe.from_frame = 0;
  probe.to_frame = 59;
  scene.loads.push_back(probe);
  SceneCut cut;
  cut.key = "cuts[0]";
  cut.a = Vec3(c.x(), b.lo.y() - 0.1 * s.y(), b.hi.z() + 0.05 * s.z());
  cut.b = Vec3(c.x(), b.hi.y() + 0.1 * s.y(), b.hi.z() + 0.05 * s.z());
  cut.sweep = Vec3(0, 0, -0.7 * s.z());
  cut.from_frame = 10;
  cut.to_frame = 50;
  scene.cuts.push_back(cut);
  scene.cg.tolerance = 1e-4;
  scene.frames = 60;
  scene.output_every = 1000;  // the last frame only: the table is about the solver
  return scene;
}

// Frames 10-50 of a played cut scene, from its stats.csv.
struct CutFrames {
  std::vector<double> frame, cut, setup, solve, iters, resid, pc_setup;
};

CutFrames play_cut_scene(const Scene& sc, const std::filesystem::path& dir, const char* keep_as = nullptr) {
  CutFrames out;
  std::filesystem::remove_all(dir);
  SceneRunOptions ro;
  ro.out_dir = dir.string();
  ro.on_frame = [&](int f, const Eigen::VectorXd&, const FrameStats& st) {
    if (f >= 10 && f <= 50) out.pc_setup.push_back(st.preconditioner_setup_ms);
  };
  run_scene(sc, ro);
  if (keep_as)  // inspect a configuration's per-frame stats
    std::filesystem::copy_file(dir / "stats.csv", keep_as, std::filesystem::copy_options::overwrite_existing);
  // stats.csv: frame,...,frame_ms,setup_ms,cheaper_preconditioner,relinearized,outside_ms,cut_ms,tets
  std::ifstream in(dir / "stats.csv");
  std::string line;
  std::getline(in, line);
  std::vector<std::string> head;
  {
    std::stringstream hs(line);
    for (std::string h; std::getline(hs, h, ',');) head.push_back(h);
  }
  auto col = [&](const char* name) { return std::size_t(std::find(head.begin(), head.end(), name) - head.begin()); };
  while (std::getline(in, line)) {
    std::vector<double> v;
    std::stringstream ls(line);
    for (std::string x; std::getline(ls, x, ',');) v.push_back(std::stod(x));
    const int f = int(v[col("frame")]);
    if (f < 10 || f > 50) continue;
    // The whole frame: what ran before the solver step (cut, backends' updates, loads) and the step.
    out.frame.push_back(v[col("frame_ms")] + v[col("outside_ms")]);
    out.cut.push_back(v[col("cut_ms")]);
    out.setup.push_back(v[col("setup_ms")]);
    out.solve.push_back(v[col("solve_ms")]);
    out.iters.push_back(v[col("iterations")]);
    out.resid.push_back(v[col("relative_residual")]);
  }
  std::filesystem::remove_all(dir);
  return out;
}

double pct(std::vector<double> x, double q) {
  if (x.empty()) return 0;
  std::sort(x.begin(), x.end());
  return x[std::min(x.size() - 1, std::size_t(q * double(x.size() - 1) + 0.5))];
}

void section_cut_scene(const std::string& organ_file, Csv& csv) {
  const TetMesh organ = largest_part(read_tet_mesh(organ_file));
  const std::string organ_path = (std::filesystem::temp_directory_path() / "incise-bench-cut-organ.vtu").string();
  write_tet_mesh(organ, organ_path);
  const Scene scene = organ_cut_scene(organ, organ_path);
  std::printf("\norgan cut scene: %s, %zu tets, corotational, probe over 60 frames, blade through the middle over "
              "frames 10-50, tolerance 1e-4; over frames 10-50: frame = everything before the solver step (cut, updates, loads) + the step (ms), its parts (median), CG "
              "iterations median/max, worst residual, factorizations started while cutting show as a busy core\n",
              organ_file.c_str(), organ.num_tets());
  std::printf("  %-28s %8s %8s %8s %8s %8s %8s %10s %17s %13s\n", "preconditioner", "median", "p95", "max", "cut",
              "setup", "solve", "iterations", "residual med/max", "pc setup m/x");
  struct Config {
    const char* name;
    Preconditioner pc;
    int settle;
    double budget_ms = 0;
    AggregationAmgOptions amg = {};
    bool settle_amg = false;  // the factor's settle policy with amg instead of block-Jacobi
  };
  AggregationAmgOptions multiplicative, ring1, ring1_multiplicative, lazy, ring2, ring3;
  multiplicative.cycle = AggregationAmgOptions::Cycle::Multiplicative;
  ring1.ring = 1;
  ring2.ring = 2;
  ring3.ring = 3;
  ring1_multiplicative = ring1;
  ring1_multiplicative.cycle = AggregationAmgOptions::Cycle::Multiplicative;
  lazy.topology_rebuild_iterations = 20;
  const Config configs[] = {{"cholesky (stale factor)", Preconditioner::Cholesky, 0},
                            {"cholesky settle 3 block-jacobi", Preconditioner::Cholesky, 3},
                            {"block-jacobi", Preconditioner::BlockJacobi, 0},
                            {"jacobi", Preconditioner::Jacobi, 0},
                            {"amg", Preconditioner::Amg, 0},
                            {"amg multiplicative", Preconditioner::Amg, 0, 0, multiplicative},
                            {"amg ring 1", Preconditioner::Amg, 0, 0, ring1},
                            {"amg ring 2", Preconditioner::Amg, 0, 0, ring2},
                            {"amg ring 3", Preconditioner::Amg, 0, 0, ring3},
                            {"amg lazy (rebuild >20 it)", Preconditioner::Amg, 0, 0, lazy},
                            {"cholesky settle 3 + amg (default)", Preconditioner::Cholesky, 3, 0, {}, true},
                            {"settle block-jacobi 16 ms", Preconditioner::Cholesky, 3, 16.0},
                            {"default budget 16 ms", Preconditioner::Cholesky, 3, 16.0, {}, true},
                            {"block-jacobi budget 16 ms", Preconditioner::BlockJacobi, 0, 16.0},
                            {"amg budget 16 ms", Preconditioner::Amg, 0, 16.0},
                            {"default with multiplicative amg", Preconditioner::Cholesky, 3, 0, multiplicative, true},
                            {"default with amg ring 1", Preconditioner::Cholesky, 3, 0, ring1, true},
                            {"default with multiplicative amg ring 1", Preconditioner::Cholesky, 3, 0, ring1_multiplicative, true},
                            {"default budget 16 ms with multiplicative amg", Preconditioner::Cholesky, 3, 16.0, multiplicative, true}};
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "incise-bench-cut-scene";
  // INCISE_BENCH_CUT_CONFIGS="amg,block-jacobi": only the configurations of these names (quick runs).
  const std::string filter = std::getenv("INCISE_BENCH_CUT_CONFIGS") ? std::getenv("INCISE_BENCH_CUT_CONFIGS") : "";
  for (const Config& cfg : configs) {
    if (!filter.empty()) {
      bool hit = false;
      std::stringstream fs(filter);
      for (std::string f; std::getline(fs, f, ',');) hit = hit || std::string(cfg.name) == f;
      if (!hit) continue;
    }
    Scene sc = scene;
    sc.cg.preconditioner = cfg.pc;
    sc.cholesky.settle_frames = cfg.settle;
    sc.cg.budget_ms = cfg.budget_ms;
    sc.amg = cfg.amg;
    sc.cholesky.settle_with_amg = cfg.settle_amg;
    const std::string keep = std::getenv("INCISE_BENCH_KEEP")
                                 ? std::string(std::getenv("INCISE_BENCH_KEEP")) + "-" + std::to_string(&cfg - configs) + ".csv"
                                 : "";
    const CutFrames cf = play_cut_scene(sc, dir, keep.empty() ? nullptr : keep.c_str());
    const auto &frame = cf.frame, &cutms = cf.cut, &setup = cf.setup, &solve = cf.solve, &iters = cf.iters,
               &resid = cf.resid, &pc_setup = cf.pc_setup;
    const double worst = resid.empty() ? 0.0 : *std::max_element(resid.begin(), resid.end());
    std::printf("  %-28s %8.1f %8.1f %8.1f %8.1f %8.1f %8.1f %5.0f/%-4.0f %8.1e/%-8.1e %6.1f/%-6.1f\n", cfg.name,
                pct(frame, 0.5), pct(frame, 0.95), pct(frame, 1.0), pct(cutms, 0.5), pct(setup, 0.5), pct(solve, 0.5),
                pct(iters, 0.5), pct(iters, 1.0), pct(resid, 0.5), worst, pc_setup.empty() ? 0.0 : pct(pc_setup, 0.5),
                pc_setup.empty() ? 0.0 : pct(pc_setup, 1.0));
    csv.row("cut-scene", cfg.name, organ.num_tets(), pct(frame, 0.5), pct(frame, 0.95), pct(frame, 1.0), pct(cutms, 0.5),
            pct(setup, 0.5), pct(solve, 0.5), pct(iters, 0.5), worst);
  }
  std::filesystem::remove_all(dir);
}

// y = D x: an operator that costs one vector pass, for timing CG's own vector work.
class DiagonalOperator : public LinearOperator {
public:
  explicit DiagonalOperator(const Eigen::VectorXd& d) : d_(d) {
    for (Eigen::Index i = 0; i < d_.size(); ++i)
      if (!(d_[i] > 0)) d_[i] = 1;
  }
  Eigen::Index rows() const override { return d_.size(); }
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const override { y = d_.cwiseProduct(x); }
  const Eigen::VectorXd& diagonal() const override { return d_; }

private:
  Eigen::VectorXd d_;
};

// Thread scaling (issue 37): each parallel pass of a frame, and the organ cut scene's whole
// frame (standard, nodal-averaged and edge-smoothed tets), on 1, 2, 4, ... threads up to the
// machine's (tbb::global_control), with the serial
// share Amdahl's law gives from the speed-up S on p threads: s = (p / S - 1) / (p - 1).
// Passes (median of 15, ms): K x, the block-Jacobi and multigrid applications, the
// relinearization (every tet's rotation and the diagonal blocks) and a tenth of it (what a budget too
// small for every rotation refreshes a frame), the multigrid's coarse factor (what every
// patch after a cut step refactors), and CG's vector work per
// iteration (a Jacobi CG of 40 iterations on a diagonal operator, less its products and
// applications).
void section_scaling(const std::vector<std::string>& organ_files, long box_tets, Csv& csv) {
  std::vector<int> threads{1};
  const int hw = int(std::thread::hardware_concurrency());
  for (int t = 2; t <= std::max(hw, 1); t *= 2) threads.push_back(t);
  if (threads.back() != hw && hw > 1) threads.push_back(hw);
  auto serial_share = [](double t1, double tp, int p) {
    if (p < 2 || !(tp > 0)) return 0.0;
    return (double(p) * tp / t1 - 1) / double(p - 1);
  };
  auto header = [&](const char* first) {
    std::printf("  %-30s", first);
    for (int t : threads) std::printf(" %7d t", t);
    std::printf(" %9s %8s\n", "speed-up", "serial");
  };
  auto row = [&](const std::string& mesh, const std::string& name, std::size_t tets, const std::vector<double>& ms) {
    std::printf("  %-30s", name.c_str());
    for (double m : ms) std::printf(" %9.3f", m);
    const double S = ms.front() / ms.back();
    const double s = serial_share(ms.front(), ms.back(), threads.back());
    std::printf(" %8.2fx %8.2f\n", S, s);
    csv.row("scaling", mesh + " " + name, tets, ms.front(), ms.back(), threads.back(), S, s);
  };
  struct Mesh {
    std::string name;
    TetMesh mesh;
    bool organ;
  };
  std::vector<Mesh> meshes;
  for (const std::string& f : organ_files) meshes.push_back({f, largest_part(read_tet_mesh(f)), true});
  if (box_tets > 0) {
    const int n = std::max(2, int(std::lround(std::cbrt(double(box_tets) / 12))));  // 2n x n x n cubes, 6 tets each
    meshes.push_back({"box", make_box(Vec3(2, 1, 1), {2 * n, n, n}), false});
  }
  for (const Mesh& me : meshes) {
    const TetMesh& m = me.mesh;
    std::printf("\nthread scaling on %s (%zu tets), corotational, ms per pass (median of 15) on each thread count\n",
                me.name.c_str(), m.num_tets());
    header("pass");
    for (Formulation form : {Formulation::Standard, Formulation::NodalAveraged, Formulation::EdgeSmoothed}) {
      const Box b(m);
      FemSimulationOptions opt;
      opt.kind = FemKind::Corotational;
      opt.formulation = form;
      opt.cg.tolerance = 1e-4;
      opt.cg.preconditioner = Preconditioner::Amg;
      FemSimulation sim(m, material(5e3, 0.4), opt);
      for (VertexId v : m.vertices()) {
        const Vec3 p = m.rest(v);
        if (p.z() < b.lo.z() + 0.15 * b.size().z()) sim.fix(v);
        if (p.z() > b.hi.z() - 0.05 * b.size().z()) sim.set_force(v, Vec3(0, 0, -1e-3));
      }
      sim.step();
      const Eigen::VectorXd u = sim.displacement();
      AggregationAmg amg(sim.model(), opt.amg);
      amg.setup(sim.model(), &sim.free_mask());
      BlockJacobi bj;
      bj.setup(sim.model(), &sim.free_mask());
      const auto jac = make_preconditioner(Preconditioner::Jacobi);
      jac->setup(sim.model(), &sim.free_mask());
      const DiagonalOperator diag(sim.model().diagonal());
      Eigen::VectorXd r = Eigen::VectorXd::Random(sim.model().rows()), z;
      for (std::size_t i = 0; i < sim.free_mask().size(); ++i)
        if (!sim.free_mask()[i]) r[Eigen::Index(i)] = 0;
      auto med15 = [](auto&& f) {
        std::vector<double> t;
        for (int k = 0; k < 15; ++k) {
          const auto t0 = std::chrono::steady_clock::now();
          f();
          t.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
        }
        return pct(t, 0.5);
      };
      std::vector<double> kx, bja, amga, relin, partial, vec, coarse;
      const std::size_t tenth = std::max<std::size_t>(1, sim.model().rotation_packets() / 10);
      std::size_t cursor = 0;
      for (int t : threads) {
        tbb::global_control gc(tbb::global_control::max_allowed_parallelism, std::size_t(t));
        kx.push_back(med15([&] { sim.model().multiply(r, z); }));
        bja.push_back(med15([&] { bj.apply(r, z); }));
        amga.push_back(med15([&] { amg.apply(r, z); }));
        relin.push_back(med15([&] { sim.model().update_rotations(u); }));
        // The coarse factor a patch after each cut step refactors (timed inside a rebuild).
        {
          std::vector<double> f;
          for (int k = 0; k < 15; ++k) {
            amg.mark_stale();
            amg.setup(sim.model(), &sim.free_mask());
            f.push_back(amg.build_stats().factor_ms);
          }
          coarse.push_back(pct(f, 0.5));
        }
        // What a budget too small for every rotation refreshes a frame: a tenth, in turn.
        partial.push_back(med15([&] {
          sim.model().update_rotations_partial(u, cursor, tenth);
          cursor += tenth;
        }));
        // CG's own vector work: 40 iterations on a diagonal operator of the model's size (the
        // operator's and Jacobi's passes, timed alone, taken off).
        const double diag_ms = med15([&] { diag.multiply(r, z); });
        const double jac_ms = med15([&] { jac->apply(r, z); });
        CgOptions co;
        co.tolerance = 1e-300;
        co.max_iterations = 40;
        ConjugateGradient cg(co);
        cg.set_preconditioner(Preconditioner::Jacobi);
        cg.compute(diag, &sim.free_mask());
        const double cg_ms = med15([&] {
          Eigen::VectorXd x = Eigen::VectorXd::Zero(r.size());
          cg.solve_with_guess(r, x);
        });
        const SolveStats& st = cg.stats();
        vec.push_back((cg_ms - st.products * diag_ms - st.iterations * jac_ms) / std::max(1, st.iterations));
      }
      const std::string f = std::string(formulation_name(form));
      row(me.name, "K x, " + f, m.num_tets(), kx);
      row(me.name, "relinearization, " + f, m.num_tets(), relin);
      row(me.name, "a tenth of it, " + f, m.num_tets(), partial);
      row(me.name, "multigrid coarse factor, " + f, m.num_tets(), coarse);
      if (form == Formulation::Standard) {
        row(me.name, "block-Jacobi apply", m.num_tets(), bja);
        row(me.name, "multigrid apply", m.num_tets(), amga);
        row(me.name, "CG vector work / iteration", m.num_tets(), vec);
      }
    }
    if (!me.organ) continue;
    // The cut scene: its frames 10-50 on each thread count.
    const std::string organ_path = (std::filesystem::temp_directory_path() / "incise-bench-scaling-organ.vtu").string();
    write_tet_mesh(m, organ_path);
    const Scene scene = organ_cut_scene(m, organ_path);
    const std::filesystem::path dir = std::filesystem::temp_directory_path() / "incise-bench-scaling";
    std::printf("  organ cut scene (default settings), frames 10-50: median / p95 frame, median cut, setup, solve "
                "(of it the preconditioner's setup), iterations med/max\n");
    for (Formulation form : {Formulation::Standard, Formulation::NodalAveraged, Formulation::EdgeSmoothed}) {
      Scene sc = scene;
      sc.formulation = form;
      std::vector<double> frame_med;
      for (int t : threads) {
        tbb::global_control gc(tbb::global_control::max_allowed_parallelism, std::size_t(t));
        const CutFrames cf = play_cut_scene(sc, dir);
        frame_med.push_back(pct(cf.frame, 0.5));
        std::printf("    %-15s %2d threads: %7.1f / %-7.1f cut %6.2f setup %6.2f solve %6.2f (%5.2f) it %3.0f/%-3.0f\n",
                    formulation_name(form).data(), t, pct(cf.frame, 0.5), pct(cf.frame, 0.95), pct(cf.cut, 0.5),
                    pct(cf.setup, 0.5), pct(cf.solve, 0.5), pct(cf.pc_setup, 0.5), pct(cf.iters, 0.5), pct(cf.iters, 1.0));
        csv.row("scaling-cut-scene", me.name + " " + std::string(formulation_name(form)), m.num_tets(), t,
                pct(cf.frame, 0.5), pct(cf.frame, 0.95), pct(cf.cut, 0.5), pct(cf.setup, 0.5), pct(cf.solve, 0.5));
      }
      row(me.name, "cut frame (median), " + std::string(formulation_name(form)), m.num_tets(), frame_med);
    }
  }
}

// What the aggregation multigrid costs on the organ: one build's phases (aggregation,
// prolongator, coarse operator, coarse factorization), the coarse size, and one application
// against a block-Jacobi application and a product K x; the organ held at the bottom and
// pressed at the top, corotational, one frame solved to 1e-4 first (so rotations are set).
void section_amg_build(const std::string& organ_file, Csv& csv) {
  const TetMesh organ = largest_part(read_tet_mesh(organ_file));
  const Box b(organ);
  std::printf("\namg build on %s (%zu tets, %zu vertices), corotational: per build ms (median of 5), coarse size, "
              "and one application against block-Jacobi and K x, and block-Jacobi's setup (median of 20)\n",
              organ_file.c_str(), organ.num_tets(), organ.num_vertices());
  std::printf("  %-22s %6s %8s %8s %9s %8s %8s %8s %8s %8s %8s %8s %8s\n", "variant", "aggr.", "coarse n", "nnz(L)",
              "aggregate", "P", "A_c", "factor", "total", "apply", "bj apply", "K x", "bj setup");
  struct Variant {
    int ring;
    bool rotations, nodal;  // nodal: nodal-averaged tets (their K reaches the 2-ring)
  };
  for (const Variant& var : {Variant{1, true, false}, Variant{1, false, false}, Variant{2, true, false},
                             Variant{2, false, false}, Variant{2, true, true}, Variant{3, true, false}}) {
      const int ring = var.ring;
      const bool rotations = var.rotations, nodal = var.nodal;
      FemSimulationOptions opt;
      opt.kind = FemKind::Corotational;
      if (nodal) opt.formulation = Formulation::NodalAveraged;
      opt.cg.tolerance = 1e-4;
      opt.cg.preconditioner = Preconditioner::Amg;
      opt.amg.ring = ring;
      opt.amg.rotations = rotations;
      FemSimulation sim(organ, material(5e3, 0.4), opt);
      for (VertexId v : organ.vertices()) {
        const Vec3 p = organ.rest(v);
        if (p.z() < b.lo.z() + 0.15 * b.size().z()) sim.fix(v);
        if (p.z() > b.hi.z() - 0.05 * b.size().z()) sim.set_force(v, Vec3(0, 0, -1e-3));
      }
      sim.step();
      std::vector<double> phase[5], apply, bj, kx, bj_setup;
      AggregationAmg amg(sim.model(), opt.amg);
      BlockJacobi jac;
      for (int k = 0; k < 5; ++k) {
        amg.mark_stale();
        amg.setup(sim.model(), &sim.free_mask());
        const AmgBuildStats& st = amg.build_stats();
        const double p5[5] = {st.aggregate_ms, st.prolongator_ms, st.coarse_ms, st.factor_ms, st.total_ms};
        for (int i = 0; i < 5; ++i) phase[i].push_back(p5[i]);
      }
      jac.setup(sim.model(), &sim.free_mask());
      Eigen::VectorXd r = Eigen::VectorXd::Random(sim.model().rows()), z;
      for (std::size_t i = 0; i < sim.free_mask().size(); ++i)
        if (!sim.free_mask()[i]) r[Eigen::Index(i)] = 0;
      auto time = [&](std::vector<double>& out, auto&& f) {
        for (int k = 0; k < 20; ++k) {
          const auto t0 = std::chrono::steady_clock::now();
          f();
          out.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
        }
      };
      time(apply, [&] { amg.apply(r, z); });
      time(bj, [&] { jac.apply(r, z); });
      time(kx, [&] { sim.model().multiply(r, z); });
      time(bj_setup, [&] { jac.setup(sim.model(), &sim.free_mask()); });
      auto med = [](std::vector<double> x) {
        std::sort(x.begin(), x.end());
        return x[x.size() / 2];
      };
      const AmgBuildStats& st = amg.build_stats();
      char name[64];
      std::snprintf(name, sizeof name, "ring %d%s", ring, nodal ? ", nodal-averaged" : rotations ? "" : ", translations");
      std::printf("  %-22s %6zu %8zu %8zu %9.2f %8.2f %8.2f %8.2f %8.2f %8.3f %8.3f %8.3f %8.3f\n", name, st.aggregates,
                  st.coarse_unknowns, st.factor_nonzeros, med(phase[0]), med(phase[1]), med(phase[2]), med(phase[3]),
                  med(phase[4]), med(apply), med(bj), med(kx), med(bj_setup));
      csv.row("amg-build", name, organ.num_tets(), st.aggregates, st.coarse_unknowns, med(phase[2]), med(phase[3]),
              med(phase[4]), med(apply), med(kx));
    }
}

void section_warm_start(Csv& csv) {
  Cantilever c(5000);
  std::printf("\nwarm start: probe at the tip moving steadily over 40 frames, cantilever %zu tets, corotational, "
              "tolerance 1e-8; CG iterations, all operator products (iterations + each frame's start: guess, "
              "prescribed values, prediction directions), and CG time (the solves only)\n",
              c.mesh.num_tets());
  std::printf("  %-13s %10s %10s %10s %12s %12s %22s %14s %18s\n", "preconditioner", "cold", "last", "predicted",
              "last/cold", "predict/cold", "products cold/predicted", "products ratio", "solve ms ratio");
  for (Preconditioner pc : kPcs) {
    int total[3] = {0, 0, 0}, products[3] = {0, 0, 0};
    double solve_ms[3] = {0, 0, 0};
    for (int mode = 0; mode < 3; ++mode) {
      FemSimulationOptions opt;
      opt.kind = FemKind::Corotational;
      opt.cg.tolerance = 1e-8;
      opt.cg.preconditioner = pc;
      opt.cg.max_iterations = 100000;
      opt.warm_start = mode > 0;
      opt.predict = mode == 2;
      opt.cholesky.background = false;  // same factors in every mode: a fair count
      FemSimulation sim(c.mesh, material(1e5, 0.45), opt);
      std::vector<VertexId> tip;
      for (VertexId v : c.mesh.vertices()) {
        if (c.mesh.rest(v).x() < 1e-9) sim.fix(v);
        if (c.mesh.rest(v).x() > 8 - 1e-9) tip.push_back(v);
      }
      for (int f = 0; f < 40; ++f) {
        for (VertexId v : tip) sim.prescribe(v, Vec3(0, 0.002 * f, -0.01 * f));
        const FrameStats& st = sim.step();
        total[mode] += st.iterations;
        products[mode] += st.products;
        solve_ms[mode] += st.solve_ms;
      }
    }
    std::printf("  %-13s %10d %10d %10d %12.3f %12.3f %11d/%-10d %14.3f %18.3f\n", to_string(pc), total[0], total[1],
                total[2], double(total[1]) / total[0], double(total[2]) / total[0], products[0], products[2],
                double(products[2]) / products[0], solve_ms[2] / solve_ms[0]);
    csv.row("warm-start", to_string(pc), c.mesh.num_tets(), total[0], total[1], total[2], double(total[1]) / total[0],
            double(total[2]) / total[0], products[0], products[2]);
  }
}

// The tip face of a cantilever turned rigidly along a circular arc (the beam bent into an arc)
// up to `degrees`, over `frames` frames; corotational, Cholesky. The factor is stale between
// refreshes; rotated (now) against as is (before), same run, same factors (computed in the
// frame). `refactor`: CG iterations above which a fresh factor is asked for.
void section_rotated(Csv& csv) {
  Cantilever c(5000);
  const int frames = 40;
  std::printf("\nstale factor under large rotation: cantilever %zu tets, corotational, nu 0.45, tip face turned along "
              "an arc by up to 90 degrees over %d frames, tolerance 1e-8, Cholesky factor computed in the frame\n",
              c.mesh.num_tets(), frames);
  std::printf("  %-34s %14s %14s %10s %16s %12s %20s\n", "refresh rule", "it/frame as is", "it/frame rot.", "ratio",
              "factorizations", "answer diff", "ms/frame as is/rot.");
  for (int refactor : {1000000, 10}) {
    double it[2] = {0, 0}, ms[2] = {0, 0};
    int facts[2] = {0, 0};
    Eigen::VectorXd u[2];
    for (int rot = 0; rot < 2; ++rot) {
      FemSimulationOptions opt;
      opt.kind = FemKind::Corotational;
      opt.cg.tolerance = 1e-8;
      opt.cg.preconditioner = Preconditioner::Cholesky;
      opt.cg.max_iterations = 100000;
      opt.cholesky.background = false;
      opt.cholesky.refactor_iterations = refactor;
      opt.cholesky.rotate = rot == 1;
      FemSimulation sim(c.mesh, material(1e5, 0.45), opt);
      std::vector<VertexId> tip;
      for (VertexId v : c.mesh.vertices()) {
        if (c.mesh.rest(v).x() < 1e-9) sim.fix(v);
        if (c.mesh.rest(v).x() > 8 - 1e-9) tip.push_back(v);
      }
      const Vec3 centre(8, 0.5, 0.5);
      for (int f = 1; f <= frames; ++f) {
        const double theta = 0.5 * M_PI * f / frames, radius = 8 / theta;
        const Eigen::Matrix3d r = Eigen::AngleAxisd(-theta, Vec3::UnitY()).toRotationMatrix();
        const Vec3 end(radius * std::sin(theta), 0.5, 0.5 + radius * (1 - std::cos(theta)));
        for (VertexId v : tip) sim.prescribe(v, end + r * (c.mesh.rest(v) - centre) - c.mesh.rest(v));
        const FrameStats& st = sim.step();
        it[rot] += st.iterations;
        ms[rot] += st.frame_ms;
      }
      it[rot] /= frames;
      ms[rot] /= frames;
      facts[rot] = sim.cholesky() ? sim.cholesky()->factorizations() : 0;
      u[rot] = sim.displacement();
    }
    const std::string rule = refactor > 1000 ? "first factor only (stale throughout)" : "refresh above 10 it (default)";
    const double diff = (u[1] - u[0]).norm() / u[0].norm();
    std::printf("  %-34s %14.1f %14.1f %10.3f %9d / %-4d %12.1e %9.2f / %-8.2f\n", rule.c_str(), it[0], it[1],
                it[1] / it[0], facts[0], facts[1], diff, ms[0], ms[1]);
    csv.row("rotated", refactor, c.mesh.num_tets(), it[0], it[1], it[1] / it[0], facts[0], facts[1], diff, 0);
  }
}

// The library default near the factorization limit: a corotational cantilever of `tets` tets,
// 5 frames of a moving probe, tolerance 1e-6, Jacobi then Cholesky (the first frame waits for
// the first factorization); time per frame and the process's peak memory after each.
void section_size(double tets, Csv& csv) {
  Cantilever c(tets);
  std::printf("\nnear the factorization limit: cantilever %zu tets, %zu vertices, corotational, tolerance 1e-6, "
              "5 frames\n",
              c.mesh.num_tets(), c.mesh.num_vertices());
  std::printf("  %-13s %12s %22s %10s %14s\n", "preconditioner", "frame 1 ms", "frames 2-5 ms (mean)", "it total",
              "peak RSS MB");
  for (Preconditioner pc : {Preconditioner::Jacobi, Preconditioner::Cholesky}) {
    FemSimulationOptions opt;
    opt.kind = FemKind::Corotational;
    opt.cg.tolerance = 1e-6;
    opt.cg.preconditioner = pc;
    opt.cg.max_iterations = 100000;
    FemSimulation sim(c.mesh, material(1e5, 0.45), opt);
    std::vector<VertexId> tip;
    for (VertexId v : c.mesh.vertices()) {
      if (c.mesh.rest(v).x() < 1e-9) sim.fix(v);
      if (c.mesh.rest(v).x() > 8 - 1e-9) tip.push_back(v);
    }
    double first = 0, rest = 0;
    int it = 0;
    for (int f = 1; f <= 5; ++f) {
      for (VertexId v : tip) sim.prescribe(v, Vec3(0, 0, -0.02 * f));
      const FrameStats& st = sim.step();
      (f == 1 ? first : rest) += st.frame_ms;
      it += st.iterations;
    }
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    const double rss = double(ru.ru_maxrss) / 1024;  // peak so far: Jacobi runs first
    std::printf("  %-13s %12.0f %22.0f %10d %14.0f\n", to_string(pc), first, rest / 4, it, rss);
    csv.row("size", to_string(pc), c.mesh.num_tets(), first, rest / 4, it, rss, 0, 0, 0);
  }
}

void section_poisson(Csv& csv) {
  Cantilever c(5000);
  std::printf("\niterations against Poisson's ratio: cantilever %zu tets, linear, cold start, tolerance 1e-8\n",
              c.mesh.num_tets());
  std::printf("  %8s %10s %12s %10s %10s %12s %12s %12s\n", "nu", "jacobi", "block-jacobi", "cholesky", "amg", "bj/jacobi",
              "chol/jacobi", "amg/jacobi");
  for (double nu : {0.3, 0.45, 0.49, 0.499, 0.4999}) {
    int it[4] = {0, 0, 0, 0};
    for (int i = 0; i < 4; ++i) {
      FemSimulationOptions opt;
      opt.cg.tolerance = 1e-8;
      opt.cg.preconditioner = kPcs[i];
      opt.cg.max_iterations = 200000;
      FemSimulation sim(c.mesh, material(1e5, nu), opt);
      c.setup(sim);
      it[i] = sim.step().iterations;
    }
    std::printf("  %8.4f %10d %12d %10d %10d %12.3f %12.3f %12.3f\n", nu, it[0], it[1], it[2], it[3],
                double(it[1]) / it[0], double(it[2]) / it[0], double(it[3]) / it[0]);
    csv.row("poisson", nu, c.mesh.num_tets(), it[0], it[1], it[2], double(it[1]) / it[0], double(it[2]) / it[0], 0, 0);
  }
}

}  // namespace

int main(int argc, char** argv) {
  Args args(argc, argv);
  const std::string out = args.get("--out", ".");
  Csv csv(out, "fem_precond.csv", "section,setting,tets,a,b,c,d,e,f,g");
  // --only SECTION (beam, organ, cut-scene, amg-build, budget, holds, warm, poisson, rotated): one section, for quick runs.
  const std::string only = args.get("--only", "");
  auto want = [&](const char* name) { return only.empty() || only == name; };
  const std::string beam = args.get("--beam", std::string(INCISE_SOURCE_DIR) + "/samples/scenes/beam.json");
  if (want("beam")) section_beam_scene(beam, csv);
  const std::string organ = args.get("--organ", "");
  if (!want("organ")) {
  } else if (!organ.empty()) {
    const TetMesh m = read_tet_mesh(organ);
    section_organ("organ", m, -1, csv);
    section_organ("cut organ", m, 10, csv);
  } else {
    std::printf("\n(no --organ MESH: organ sections skipped; make one with `incise prepare samples/liver.inr.gz -o "
                "liver.vtu`)\n");
  }
  if (want("budget")) section_budget(args.num("--budget-tets", 30000), csv);
  if (want("holds")) section_budget_holds(csv);
  if (want("cut-scene")) {
    if (!organ.empty()) section_cut_scene(organ, csv);
    else if (!only.empty()) std::printf("\ncut-scene: needs --organ MESH\n");
  }
  if (want("amg-build")) {
    if (!organ.empty()) section_amg_build(organ, csv);
    else if (!only.empty()) std::printf("\namg-build: needs --organ MESH\n");
  }
  // --only scaling: the passes and the cut frame on each thread count (organs from --organ and
  // --organ2, a box of --scaling-box-tets, default 1M; 0: none).
  if (only == "scaling") {
    std::vector<std::string> organs;
    for (const char* key : {"--organ", "--organ2"})
      if (!args.get(key, "").empty()) organs.push_back(args.get(key, ""));
    section_scaling(organs, long(args.num("--scaling-box-tets", 1e6)), csv);
  }
  if (want("warm")) section_warm_start(csv);
  if (want("rotated")) section_rotated(csv);
  if (want("poisson")) section_poisson(csv);
  // Slow (the factorization of a large model): only on request.
  if (args.get("--size-tets", "") != "") section_size(args.num("--size-tets", 0), csv);
  std::printf("\nCSV: %s\n", csv.path().c_str());
  return 0;
}
