// Mesh improvement benchmark. Figures are relative to baselines measured in the same run:
//  1. quality before -> after (min/max dihedral, min radius ratio, tet count, seconds) for
//     each mesh, with the surface kept exactly (flat sliding only), with sliding on smooth
//     curved parts, and with that plus vertex insertion (ratios against curved printed); the
//     input mesh is the baseline; the first two also without multi-face removal (the ratios
//     on / off are printed);
//     plus what the solvers see before -> after: static CG iterations (no preconditioner and
//     Jacobi) under gravity, and the spring model's stable explicit time step;
//  2. local mode: time per improve_local call against the number of seed tets, on a 10k-tet
//     and (unless --quick) a ~1M-tet jittered box; equal ms per operation at both sizes shows
//     that a call does no O(mesh) work (calls on the small mesh overlap and find less to do).
// Usage: bench_improve [--quick] [--time-limit S] [MESH ...]   (any tet format incise reads;
// e.g. `incise prepare samples/liver.inr.gz --no-improve -o liver.vtu` makes one)
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "bench/bench_common.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "mesh/isosurface_stuffing.h"
#include "quality/components.h"
#include "quality/improve.h"
#include "sim/fem/fem_simulation.h"
#include "sim/springs/spring_model.h"
#include "testing/mesh_edits.h"

using namespace incise;

namespace {

void row(const std::string& name, const char* mode, const ImproveReport& r) {
  std::printf("%-22s %-8s dihedral %6.2f..%6.2f -> %6.2f..%6.2f  rr %.3f -> %.3f  tets %7zu -> %7zu (x%.3f)  "
              "%5.2f s  ops 23:%d 32:%d 44:%d er:%d mf:%d bf:%d sm:%d ins:%d ct:%d\n",
              name.c_str(), mode, r.min_dihedral_before, r.max_dihedral_before, r.min_dihedral_after,
              r.max_dihedral_after, r.min_radius_ratio_before, r.min_radius_ratio_after, r.tets_before, r.tets_after,
              double(r.tets_after) / double(r.tets_before), r.seconds, r.flips23, r.flips32, r.flips44,
              r.edge_removals, r.multi_face_removals, r.boundary_flips, r.smoothing_moves, r.insertions,
              r.contractions);
}

// What the solvers see: static CG iterations under gravity with the input's lowest 10% of
// each part's vertices (by z, at least 4) fixed (the same vertex ids before and after: improvement keeps ids and
// appends inserted vertices), without and with the Jacobi preconditioner, and the stable
// explicit time step of the spring model.
struct SolverFigures {
  int cg_plain = 0, cg_jacobi = 0;
  double spring_dt = 0;
};

// The lowest 10% (by z, at least 4) of each connected part's vertices, so every part is held.
std::vector<VertexId> bottom(const TetMesh& m) {
  const TetComponents parts = tet_components(m);
  std::vector<std::vector<VertexId>> by_part(parts.count);
  std::vector<int> part(m.vertex_capacity(), -1);
  for (TetId t : m.tets())
    for (VertexId v : m.tet_vertices(t))
      if (part[v.idx()] < 0) by_part[part[v.idx()] = parts.of_tet[t.idx()]].push_back(v);
  std::vector<VertexId> out;
  for (auto& vs : by_part) {
    std::sort(vs.begin(), vs.end(), [&](VertexId a, VertexId b) { return m.rest(a).z() < m.rest(b).z(); });
    const double zcut = m.rest(vs.front()).z() + 0.1 * (m.rest(vs.back()).z() - m.rest(vs.front()).z());
    for (std::size_t i = 0; i < vs.size() && (i < 4 || m.rest(vs[i]).z() <= zcut); ++i) out.push_back(vs[i]);
  }
  return out;
}

SolverFigures solver_figures(const TetMesh& m, const std::vector<VertexId>& fixed) {
  const MaterialTable mat(Material{1e5, 0.45, 1000});
  SolverFigures out;
  for (Preconditioner p : {Preconditioner::None, Preconditioner::Jacobi}) {
    FemSimulationOptions o;
    o.cg.tolerance = 1e-8;
    o.cg.max_iterations = 200000;
    o.cg.preconditioner = p;
    o.gravity = Vec3(0, 0, -9.81);
    FemSimulation sim(m, mat, o);
    for (VertexId v : fixed) sim.fix(v);
    (p == Preconditioner::None ? out.cg_plain : out.cg_jacobi) = sim.step().iterations;
  }
  out.spring_dt = SpringModel(m, mat).stable_time_step();
  return out;
}

struct Mode {
  const char* name;
  bool slide_curved, insertion, multi_face;
};
// Each "-mf0" mode is the one before it without multi-face removal: the pair is measured in the
// same run, and the line after it gives the ratios on / off.
constexpr Mode kModes[] = {{"exact", false, false, true},  {"exact-mf0", false, false, false},
                           {"curved", true, false, true},  {"curved-mf0", true, false, false},
                           {"insert", true, true, true}};

void global(const std::string& name, const TetMesh& input, double time_limit) {
  TetMesh dense = input;
  dense.compact();
  const std::vector<VertexId> fixed = bottom(dense);
  const SolverFigures before = solver_figures(dense, fixed);
  ImproveReport previous, curved;
  for (const Mode& mode : kModes) {
    TetMesh m = dense;
    ImproveOptions o;
    o.time_limit_s = time_limit;
    o.slide_curved = mode.slide_curved;
    o.volume_tolerance = 1;  // `curved` slides without the volume limit (docs/improve.md's table)
    o.insertion = mode.insertion;
    o.multi_face_removal = mode.multi_face;
    const ImproveReport r = improve(m, o);
    row(name, mode.name, r);
    if (!mode.multi_face)
      std::printf("%-22s %-8s multi-face on/off: min dihedral %.2f / %.2f, max %.2f / %.2f, rr %.3f / %.3f, "
                  "tets x%.3f, time x%.2f\n",
                  name.c_str(), "", previous.min_dihedral_after, r.min_dihedral_after, previous.max_dihedral_after,
                  r.max_dihedral_after, previous.min_radius_ratio_after, r.min_radius_ratio_after,
                  double(previous.tets_after) / double(r.tets_after), previous.seconds / r.seconds);
    if (mode.insertion)  // against "curved", the same options without insertion, same run
      std::printf("%-22s %-8s insertion on/off: min dihedral %.2f / %.2f, max %.2f / %.2f, rr %.3f / %.3f, "
                  "tets x%.3f, time x%.2f\n",
                  name.c_str(), "", r.min_dihedral_after, curved.min_dihedral_after, r.max_dihedral_after,
                  curved.max_dihedral_after, r.min_radius_ratio_after, curved.min_radius_ratio_after,
                  double(r.tets_after) / double(curved.tets_after), r.seconds / curved.seconds);
    if (mode.slide_curved && mode.multi_face && !mode.insertion) curved = r;
    previous = r;
    m.compact();
    const SolverFigures after = solver_figures(m, fixed);
    std::printf("%-22s %-8s solver: CG %d -> %d (x%.2f), Jacobi-CG %d -> %d (x%.2f), spring stable dt x%.2f\n",
                name.c_str(), "", before.cg_plain, after.cg_plain, double(after.cg_plain) / before.cg_plain,
                before.cg_jacobi, after.cg_jacobi, double(after.cg_jacobi) / before.cg_jacobi,
                after.spring_dt / before.spring_dt);
  }
}

TetMesh jittered_box(int n, double amount) {
  TetMesh m = make_box(Vec3(1, 1, 1), {n, n, n});
  testing::jitter(m, amount, 1);
  m.discard_change();
  return m;
}

void local(const std::string& name, TetMesh m) {
  std::mt19937 rng(3);
  for (int seeds : {1, 10, 100}) {
    // Seeds: the star of a random vertex, grown to `seeds` tets by vertex adjacency.
    double total = 0;
    int ops = 0;
    const int calls = 20;
    for (int c = 0; c < calls; ++c) {
      std::vector<TetId> s = {testing::random_tet(m, rng)};
      for (std::size_t i = 0; s.size() < static_cast<std::size_t>(seeds) && i < s.size(); ++i)
        for (VertexId v : m.tet_vertices(s[i]))
          for (TetId u : m.incident_tets(v))
            if (s.size() < static_cast<std::size_t>(seeds) && std::find(s.begin(), s.end(), u) == s.end()) s.push_back(u);
      const double t0 = bench::now_ms();
      const ImproveReport r = improve_local(m, s);  // no budget: runs until the region is done
      total += bench::now_ms() - t0;
      ops += r.flips23 + r.flips32 + r.flips44 + r.edge_removals + r.multi_face_removals + r.smoothing_moves;
    }
    std::printf("local %-14s %8zu tets  %4d seeds  %8.3f ms/call  %6.1f ops/call  %6.3f ms/op\n", name.c_str(),
                m.num_tets(), seeds, total / calls, double(ops) / calls, total / std::max(ops, 1));
  }
}

}  // namespace

int main(int argc, char** argv) {
  bench::Args args(argc, argv);
  const bool quick = args.flag("--quick");
  const double limit = args.num("--time-limit", 30);
  std::vector<std::string> files;
  for (std::size_t i = 0; i < args.argv.size(); ++i) {
    if (args.argv[i] == "--time-limit") {
      ++i;
      continue;
    }
    if (args.argv[i].rfind("--", 0) != 0) files.push_back(args.argv[i]);
  }
  std::printf("# global improve: input (baseline) -> improved; exact = surface kept, curved = sliding on smooth parts, "
              "insert = curved + insertion, -mf0 = without multi-face removal\n");
  global("box8-jitter0.4", jittered_box(8, 0.4), limit);
  StuffingOptions so;
  so.cell_size = quick ? 0.2 : 0.1;
  global("stuffed-sphere", isosurface_stuffing([](const Vec3& p) { return p.norm() - 1; }, Vec3(-1.1, -1.1, -1.1),
                                               Vec3(1.1, 1.1, 1.1), so),
         limit);
  for (const std::string& f : files) {
    TetMesh m = read_tet_mesh(f);
    m.discard_change();
    global(std::filesystem::path(f).filename().string(), m, limit);
  }
  std::printf("# local improve: ms per call (20 calls, 2 rings, no budget) vs seeds; compare the two sizes\n");
  local("box12", jittered_box(12, 0.2));  // ~10k tets
  if (!quick) local("box55", jittered_box(55, 0.2));  // ~1M tets
  return 0;
}
