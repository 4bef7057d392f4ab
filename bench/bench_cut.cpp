// Cutting, measured (issue figures; README "Cutting"). Five CSV blocks:
//  1. step_to_solver_ready: a progressive cut on boxes of ~10k, ~100k and ~1M tets, the blade
//     sized in cells so each step cuts about the same number of tets; per step: cut (with the
//     local improvement), FEM apply, spring apply, against rebuilding both backends on the cut
//     mesh. Apart: building the cutter's first-contact grid (setup, once per cutter), a step of
//     the blade above the body (no contact: must cost nothing), and the first step of a cut
//     (first contact: a query of the grid near the blade).
//  2. quality_after_cuts: 100 random blade steps (20 cuts of 5 steps, fixed seed, each cut
//     finished) on the organ: subdivision with the default per-step improvement (with and without
//     edge contraction), more and unlimited work, without improvement, and removal; against the
//     bound the cut mesh's sharpest boundary edge sets.
//  3. snap_trade: plane cuts of the liver for several snap thresholds: quality of the result,
//     new tets, and the largest distance of a cut-face vertex from the plane (in mean edge
//     lengths).
//  5. progressive: one blade motion sliced into 1 .. 4000 steps (and one tenth of an edge per
//     step): tets added per crossed tet, cut area against the single step, parts, quality, and
//     per-step times (median, p95, max) with and without the improvement.
//  4. beam_ratio: a beam clamped at both ends under gravity, cut through at midspan: midspan
//     sag after / before, against beam theory: 3 (Euler-Bernoulli: two cantilevers of half
//     the length), 2.78 with shear (Timoshenko) for this beam's L/h = 10.
// Usage: bench_cut [--quick] [--no-1m] [--provisional] [--no-exact-volumes] [--only step|quality|snap|beam|progressive|curved|curved-organ|deformed] [--case NAME_PART] [--steps N]
//                  [ORGAN]   (default samples/liver.msh; --case, --steps: only the progressive, curved or
//                  curved-organ rows whose case name contains NAME_PART, with N steps (no offset rows), for
//                  profiling; INCISE_BENCH_DEFORMED_OUT=DIR: --only
//                  deformed writes each cut mesh there; INCISE_BENCH_QUALITY_OUT=DIR: --only quality each
//                  variant's; INCISE_BENCH_CURVED_OUT=DIR: --only curved writes each
//                  path's cut mesh there, and the offset drags' below 10 deg; --only curved-organ each drag's;
//                  INCISE_BENCH_STEPS=1: --only curved-organ prints every step's times on stderr;
//                  INCISE_BENCH_DRAGS=1: --only curved and curved-organ print each offset drag on stderr;
//                  INCISE_BENCH_OFFSET=K: curved-organ runs only the offset drags K)
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <unordered_map>
#include <limits>
#include <random>
#include <string>
#include <unordered_set>
#include <vector>

#include "cut/cutter.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "mesh/rest_bounds.h"
#include "quality/boundary_angle.h"
#include "quality/thin_parts.h"
#include "quality/components.h"
#include "quality/metrics.h"
#include "sim/fem/fem_simulation.h"
#include "sim/springs/spring_model.h"
#include "testing/draws.h"

using namespace incise;
using incise::testing::draw_vec3;
using incise::testing::random_blades;
using incise::testing::RandomBlade;

namespace {
// --provisional: every row with CutOptions::provisional (a paired run against the default).
bool g_provisional = false;
bool g_exact_volumes = CutOptions{}.exact_volumes;  // --no-exact-volumes: cuts may move label volumes by a hair


double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}


// A fingerprint of the mesh (tets, labels, face tags, rest positions bit for bit): equal
// fingerprints say two runs gave the same mesh (how a speed-up shows it changed nothing).
std::uint64_t fingerprint(const TetMesh& m) {
  std::uint64_t h = 1469598103934665603ull;
  auto mix = [&](std::uint64_t x) {
    for (int i = 0; i < 8; ++i, x >>= 8) h = (h ^ (x & 0xff)) * 1099511628211ull;
  };
  for (TetId t : m.tets()) {
    for (VertexId v : m.tet_vertices(t)) mix(v.idx());
    mix(std::uint64_t(m.label(t)));
    for (int f = 0; f < 4; ++f) mix(m.face_tag(t, f));
  }
  for (VertexId v : m.vertices())
    for (int k = 0; k < 3; ++k) {
      std::uint64_t bits;
      const double x = m.rest(v)[k];
      std::memcpy(&bits, &x, sizeof bits);
      mix(bits);
    }
  return h;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, std::size_t(p * double(v.size())))];
}

// ---- 1 -------------------------------------------------------------------------------------
void step_to_solver_ready(bool quick, bool with_1m) {
  std::printf("# step_to_solver_ready\n");
  std::printf("tets,cells,ms_grid_build,ms_step_no_contact,first_step_ms,steps,tets_cut_per_step,ms_cut,ms_improve,ms_apply_fem,ms_apply_springs,"
              "ms_step_total,us_per_cut_tet,ms_rebuild_fem,ms_rebuild_springs,ratio_rebuild_over_step\n");
  std::vector<int> sizes = {12, 26};
  if (with_1m && !quick) sizes.push_back(55);
  for (int n : sizes) {
    TetMesh mesh = make_box(Vec3(n, n, n), {n, n, n});  // unit cells
    mesh.discard_change();
    const MaterialTable mat(Material{1e4, 0.3, 1});
    FemSimulation fem(mesh, mat);
    SpringModel springs(mesh, mat);
    CutOptions opt;  // the defaults: the improvement's budget counts operations
    opt.provisional = g_provisional;
    opt.exact_volumes = g_exact_volumes;
    const double tg = now_ms();
    Cutter cutter(mesh, opt);
    const double grid_ms = now_ms() - tg;
    // A 6-cell blade across y at x = n/2 + 0.37, entering from the top, one cell per step.
    const double x = 0.5 * n + 0.37, y0 = 0.5 * n - 3.1, y1 = 0.5 * n + 2.9;
    const int steps = quick ? 4 : 8;
    cutter.start({Vec3(x, y0, n + 1.5), Vec3(x + 0.05, y1, n + 1.5)});
    const double ta = now_ms();
    if (cutter.advance({Vec3(x, y0, n + 0.5), Vec3(x + 0.05, y1, n + 0.5)}).tets_cut != 0) std::abort();
    const double approach_ms = now_ms() - ta;
    double first = 0, cut = 0, imp = 0, afem = 0, aspr = 0;
    std::size_t cut_tets = 0;
    for (int s = 1; s <= steps + 1; ++s) {
      const double z = n + 0.5 - 1.03 * s;
      const double t0 = now_ms();
      CutStepReport r = cutter.advance({Vec3(x, y0, z), Vec3(x + 0.05, y1, z)});
      const double t1 = now_ms();
      fem.apply(r.change);
      const double t2 = now_ms();
      springs.apply(mesh, r.change);
      const double t3 = now_ms();
      if (s == 1) {
        first = t3 - t0;  // first contact: includes the grid query for the first tets
        continue;
      }
      cut += t1 - t0;
      imp += r.ms_improve;
      afem += t2 - t1;
      aspr += t3 - t2;
      cut_tets += r.tets_cut;
    }
    const double t4 = now_ms();
    { FemSimulation fresh(mesh, mat); }
    const double t5 = now_ms();
    { SpringModel fresh(mesh, mat); }
    const double t6 = now_ms();
    const double per_step = (cut + afem + aspr) / steps;
    std::printf("%zu,%d,%.2f,%.3f,%.3f,%d,%.1f,%.3f,%.3f,%.3f,%.3f,%.3f,%.2f,%.2f,%.2f,%.1f\n", mesh.num_tets(), n,
                grid_ms, approach_ms, first, steps,
                double(cut_tets) / steps, cut / steps, imp / steps, afem / steps, aspr / steps, per_step,
                1e3 * (cut + afem + aspr) / std::max<std::size_t>(cut_tets, 1), t5 - t4, t6 - t5,
                (t6 - t4) / per_step);
    std::fflush(stdout);
  }
}

// ---- 2 -------------------------------------------------------------------------------------
// Where the tets below `deg` are: at a rim (a vertex on both a cut face and a surface face),
// on the cut surface, on the body's surface, or inside.
std::string where_bad(const TetMesh& m, double deg) {
  std::vector<char> on_cut(m.vertex_capacity(), 0), on_surf(m.vertex_capacity(), 0);
  for (const auto& f : m.boundary_faces())
    for (VertexId v : f.vertices) (f.tag == kTagCut ? on_cut : on_surf)[v.idx()] = 1;
  std::size_t rim = 0, cut = 0, surf = 0, inside = 0;
  for (TetId t : m.tets()) {
    const auto& tv = m.tet_vertices(t);
    if (tet_quality(m.rest(tv[0]), m.rest(tv[1]), m.rest(tv[2]), m.rest(tv[3])).min_dihedral >= deg) continue;
    bool c = false, s = false, r = false;
    for (VertexId v : tv) {
      c |= on_cut[v.idx()];
      s |= on_surf[v.idx()];
      r |= on_cut[v.idx()] && on_surf[v.idx()];
    }
    (r ? rim : c ? cut : s ? surf : inside)++;
  }
  char buf[160];
  std::snprintf(buf, sizeof buf, "rim %zu / cut %zu / surface %zu / inside %zu", rim, cut, surf, inside);
  return buf;
}

// Why the tets below `deg` are there: `forced`, around a boundary edge sharper than that (no
// mesh of this surface does better); `front`, with a vertex on the front of a cut that ends
// inside the body (a boundary edge of interior angle about 360: the cut's two sides folded onto
// each other); `thin`, across a part thinner than a quarter of their longest edge
// (quality/thin_parts.h: only smaller tets would do better); `bridge`, a short edge (under a fifth of the tet's longest)
// through the inside joining two boundary vertices: the tissue between two sheets is thinner
// than that there, and removing the edge lays the new tets flat on the sheets while contracting
// it would glue them; `short boundary edge`, a short edge on the boundary (contraction along
// the boundary keeps ends on creases and corners; others were not revisited); `other`.
std::string why_below(const TetMesh& m, double deg) {
  std::vector<char> forced(m.tet_capacity(), 0), on_boundary(m.vertex_capacity(), 0), thin(m.tet_capacity(), 0);
  const std::vector<TetId> sharp = sharp_boundary(m, deg).tets;
  for (TetId t : sharp) forced[t.idx()] = 1;
  ThinPartOptions to;
  to.sliver_degrees = deg;
  for (TetId t : slivers_across_thin_parts(m, to, sharp)) thin[t.idx()] = 1;
  std::vector<char> on_front(m.vertex_capacity(), 0);
  for (const auto& [a, b] : reflex_boundary_edges(m, 359.0)) on_front[a.idx()] = on_front[b.idx()] = 1;
  std::unordered_set<std::uint64_t> boundary_edges;
  auto key = [](VertexId a, VertexId b) {
    return std::uint64_t(std::min(a.idx(), b.idx())) << 32 | std::max(a.idx(), b.idx());
  };
  for (const auto& f : m.boundary_faces())
    for (int k = 0; k < 3; ++k) {
      on_boundary[f.vertices[k].idx()] = 1;
      boundary_edges.insert(key(f.vertices[k], f.vertices[(k + 1) % 3]));
    }
  std::size_t n_forced = 0, n_front = 0, n_thin = 0, bridge = 0, rim_edge = 0, other = 0;
  for (TetId t : m.tets()) {
    const auto& tv = m.tet_vertices(t);
    if (tet_quality(m.rest(tv[0]), m.rest(tv[1]), m.rest(tv[2]), m.rest(tv[3])).min_dihedral >= deg) continue;
    if (forced[t.idx()]) {
      ++n_forced;
      continue;
    }
    if (on_front[tv[0].idx()] || on_front[tv[1].idx()] || on_front[tv[2].idx()] || on_front[tv[3].idx()]) {
      ++n_front;
      continue;
    }
    if (thin[t.idx()]) {
      ++n_thin;
      continue;
    }
    double shortest = 1e300, longest = 0;
    VertexId a, b;
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) {
        const double l = (m.rest(tv[i]) - m.rest(tv[j])).norm();
        longest = std::max(longest, l);
        if (l < shortest) shortest = l, a = tv[i], b = tv[j];
      }
    if (shortest < 0.2 * longest && on_boundary[a.idx()] && on_boundary[b.idx()])
      (boundary_edges.count(key(a, b)) ? rim_edge : bridge)++;
    else
      ++other;
  }
  char buf[192];
  std::snprintf(buf, sizeof buf, "forced %zu / front %zu / thin %zu / bridge %zu / short boundary edge %zu / other %zu",
                n_forced, n_front, n_thin, bridge, rim_edge, other);
  return buf;
}

void quality_after_cuts(const TetMesh& organ, const std::string& name, bool quick) {
  const int cuts = quick ? 6 : 20;
  std::printf("# quality_after_cuts (%s, %d cuts x 5 steps, each finished; bound: the sharpest boundary edge of the "
              "cut mesh, no surface-keeping mesh does better; goal: min dihedral >= min(10, bound / 2) and < 1%% of "
              "tets below 10 deg)\n", name.c_str(), cuts);
  std::printf("variant,tets,min_dihedral,max_dihedral,min_radius_ratio,tets_below_10deg,pct_below_10deg,bound_deg,"
              "goal_deg,meets_goal,pct_below_10deg_unforced,tets_below_5deg,ms_total,ms_p95_step_or_finish,ms_max,contractions,where_below_goal,why_below_goal,where_below_10deg,why_below_10deg,mesh_fingerprint\n");
  const QualityRange r0 = quality_range(organ, 10.0);
  const auto b0 = smallest_boundary_angle(organ);
  std::printf("uncut,%zu,%.3f,%.3f,%.2e,%zu,%.2f,%.2f,,,,%zu,0,0,0,0,,,,,\n", organ.num_tets(), r0.min_dihedral, r0.max_dihedral,
              r0.min_radius_ratio, r0.below, 100.0 * double(r0.below) / double(organ.num_tets()), b0 ? b0->degrees : 180.0,
              quality_range(organ, 5.0).below);
  // INCISE_BENCH_SEED picks other blades (the figures in the README are seed 2026).
  const char* seed_env = std::getenv("INCISE_BENCH_SEED");
  const unsigned seed = seed_env ? static_cast<unsigned>(std::strtoul(seed_env, nullptr, 10)) : 2026u;
  const auto blades = random_blades(organ, cuts, seed);
  struct Variant {
    const char* name;
    CutMode mode;
    bool improve;
    int work;  // operations per step (the default: CutOptions::kDefaultImproveWork); 0: unlimited
    bool collapse = true;
    double snap = CutOptions{}.snap;
  };
  // Operation budgets, not time: the figures are the same on any machine.
  for (const Variant& v : {Variant{"subdivide+improve(default: 8 ops/step)", CutMode::Subdivide, true, CutOptions::kDefaultImproveWork},
                           Variant{"subdivide+improve(default; no collapse)", CutMode::Subdivide, true, CutOptions::kDefaultImproveWork, false},
                           Variant{"subdivide+improve(40 ops/step)", CutMode::Subdivide, true, 40},
                           Variant{"subdivide+improve(default; snap 0.15)", CutMode::Subdivide, true, CutOptions::kDefaultImproveWork, true, 0.15},
                           Variant{"subdivide+improve(default; snap 0.3)", CutMode::Subdivide, true, CutOptions::kDefaultImproveWork, true, 0.3},
                           Variant{"subdivide+improve(unlimited)", CutMode::Subdivide, true, 0},
                           Variant{"subdivide", CutMode::Subdivide, false, 0}, Variant{"remove", CutMode::Remove, false, 0}}) {
    TetMesh m = organ;
    CutOptions opt;
    opt.provisional = g_provisional;
    opt.exact_volumes = g_exact_volumes;
    opt.mode = v.mode;
    opt.improve = v.improve;
    opt.improve_options.max_work = v.work;
    if (v.work == 0) opt.finish_improve_work = std::numeric_limits<int>::max();  // and no cap in finish()
    opt.improve_options.collapse = v.collapse;
    opt.snap = v.snap;
    Cutter cutter(m, opt);
    double total = 0;
    std::vector<double> ms;
    int contractions = 0;
    for (const RandomBlade& b : blades) {
      cutter.start({b.a, b.b});
      for (int s = 1; s <= 5; ++s) {
        const Vec3 off = b.sweep * (s / 5.0);
        const CutStepReport r = cutter.advance({b.a + off, b.b + off});
        total += r.ms;
        ms.push_back(r.ms);
        contractions += r.improve.contractions;
      }
      const CutStepReport fin = cutter.finish();  // the blade withdrawn: the front released
      total += fin.ms;
      ms.push_back(fin.ms);
      contractions += fin.improve.contractions;
    }
    if (const char* dir = std::getenv("INCISE_BENCH_QUALITY_OUT")) {  // each variant's mesh, for a look
      std::string file = v.name;
      for (char& c : file)
        if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
      write_tet_mesh(m, (std::filesystem::path(dir) / ("quality-" + file + ".vtu")).string());
    }
    const QualityRange q = quality_range(m, 10.0);
    const auto bound = smallest_boundary_angle(m);
    const double bdeg = bound ? bound->degrees : 180.0, goal = std::min(10.0, 0.5 * bdeg);
    const double pct = 100.0 * double(q.below) / double(m.num_tets());
    // Tets around boundary edges sharper than 10 deg are below 10 deg in any mesh of this surface.
    const double pct_free = 100.0 * double(q.below - sharp_boundary(m, 10.0).tets.size()) / double(m.num_tets());
    std::printf("%s,%zu,%.3f,%.3f,%.2e,%zu,%.2f,%.2f,%.2f,%s,%.2f,%zu,%.1f,%.2f,%.2f,%d,%s,%s,%s,%s,%016llx\n", v.name, m.num_tets(),
                q.min_dihedral, q.max_dihedral, q.min_radius_ratio, q.below, pct, bdeg, goal,
                q.min_dihedral >= goal && pct < 1 ? "yes" : "no", pct_free, quality_range(m, 5.0).below, total, percentile(ms, 0.95),
                percentile(ms, 1.0),
                contractions, where_bad(m, goal).c_str(), why_below(m, goal).c_str(), where_bad(m, 10.0).c_str(), why_below(m, 10.0).c_str(), (unsigned long long)fingerprint(m));
    std::fflush(stdout);
  }
}

// ---- 3 -------------------------------------------------------------------------------------
void snap_trade(const TetMesh& organ) {
  std::printf("# snap_trade (3 plane cuts of the organ, one at a time on a fresh copy; worst over the three)\n");
  std::printf("snap,min_dihedral,min_radius_ratio,tets_below_5deg,new_tets,max_distance_over_mean_edge\n");
  double edge = 0;
  std::size_t ne = 0;
  for (TetId t : organ.tets()) {
    const auto& tv = organ.tet_vertices(t);
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j, ++ne) edge += (organ.rest(tv[i]) - organ.rest(tv[j])).norm();
  }
  edge /= double(ne);
  const RestBounds box = rest_bounds(organ);
  const Vec3 lo = box.lo, hi = box.hi;
  const Vec3 c = 0.5 * (lo + hi);
  const std::pair<Vec3, Vec3> planes[] = {{c + 0.013 * (hi - lo), Vec3(1, 0.1, 0.05)},
                                          {c - 0.11 * (hi - lo), Vec3(0.2, 1, -0.3)},
                                          {c + 0.07 * (hi - lo), Vec3(-0.4, 0.3, 1)}};
  for (double snap : {0.0, 0.02, 0.05, 0.1, 0.2, 0.3, 0.45}) {
    QualityRange worst;
    std::size_t added = 0;
    double dist = 0;
    for (const auto& [p, n] : planes) {
      TetMesh m = organ;
      CutOptions opt;
      opt.provisional = g_provisional;
      opt.exact_volumes = g_exact_volumes;
      opt.snap = snap;
      opt.improve = false;  // the trade of snapping alone
      Cutter cutter(m, opt);
      const CutStepReport r = cutter.cut_plane(p, n);
      added += r.tets_added;
      const QualityRange q = quality_range(m);
      worst.min_dihedral = std::min(worst.min_dihedral, q.min_dihedral);
      worst.min_radius_ratio = std::min(worst.min_radius_ratio, q.min_radius_ratio);
      worst.below += q.below;
      const Vec3 un = n.normalized();
      for (const auto& f : m.boundary_faces())
        if (f.tag == kTagCut)
          for (VertexId v : f.vertices) dist = std::max(dist, std::abs(un.dot(m.rest(v) - p)));
    }
    std::printf("%.2f,%.3f,%.4f,%zu,%zu,%.4f\n", snap, worst.min_dihedral, worst.min_radius_ratio, worst.below, added, dist / edge);
    std::fflush(stdout);
  }
}

// ---- 4 -------------------------------------------------------------------------------------
// Mean z displacement of the vertices within half a cell of x = xm.
double sag_at(const TetMesh& m, const FemSimulation& fem, double xm, double h) {
  double s = 0;
  int n = 0;
  for (VertexId v : m.vertices())
    if (std::abs(m.rest(v).x() - xm) <= 0.5 * h) {
      s += fem.displacement()[3 * v.idx() + 2];
      ++n;
    }
  return n ? s / n : 0;
}

// Midspan sag of the cut beam (two cantilevers of L/2) over the clamped-clamped one, with
// shear (Timoshenko, square section of side h, shear coefficient 5/6, uniform load).
double timoshenko_cut_ratio(double L, double h, double E, double nu) {
  const double I = h * h * h * h / 12, A = h * h, G = E / (2 * (1 + nu)), k = 5.0 / 6.0;
  const double uncut = L * L * L * L / (384 * E * I) + L * L / (8 * k * G * A);
  const double half = 0.5 * L;
  const double cut = half * half * half * half / (8 * E * I) + half * half / (2 * k * G * A);
  return cut / uncut;
}

void beam_ratio(bool quick) {
  std::printf("# beam_ratio (L = 10, square section 1, clamped at both ends, gravity; cut through at x = 5.03)\n");
  std::printf("cells_along,tets,sag_uncut,sag_cut,ratio,euler_bernoulli,timoshenko\n");
  std::vector<int> res = {20, 40, 80};
  if (quick) res = {10, 20, 40};
  for (int nx : res) {
    const int ny = nx / 10;
    const double L = 10, h = L / nx;
    TetMesh mesh = make_box(Vec3(L, 1, 1), {nx, ny, ny});
    mesh.discard_change();
    FemSimulationOptions o;
    o.gravity = Vec3(0, 0, -1);
    o.cg.tolerance = 1e-10;
    o.cg.max_iterations = 200000;
    FemSimulation fem(mesh, MaterialTable(Material{1e4, 0.3, 1}), o);
    for (VertexId v : mesh.vertices())
      if (mesh.rest(v).x() == 0 || mesh.rest(v).x() == L) fem.fix(v);
    fem.step();
    const double before = sag_at(mesh, fem, 0.5 * L, h);
    CutOptions opt;
    opt.provisional = g_provisional;
    opt.exact_volumes = g_exact_volumes;
    Cutter cutter(mesh, opt);
    const CutStepReport r = cutter.cut_plane(Vec3(0.5 * L + 0.03 * h, 0, 0), Vec3(1, 0, 0));
    fem.apply(r.change);
    fem.step();
    const double after = sag_at(mesh, fem, 0.5 * L, h);
    std::printf("%d,%zu,%.6g,%.6g,%.3f,3,%.3f\n", nx, mesh.num_tets(), before, after, after / before,
                timoshenko_cut_ratio(L, 1.0, 1e4, 0.3));
    std::fflush(stdout);
  }
}

// ---- 5 -------------------------------------------------------------------------------------
// Volumes of the parts that share no vertex.
// The part (tets sharing vertices) of each tet, as a representative vertex id.
std::unordered_map<std::uint32_t, std::uint32_t> tet_parts(const TetMesh& m) {
  std::vector<std::uint32_t> parent(m.vertex_capacity());
  for (std::uint32_t i = 0; i < parent.size(); ++i) parent[i] = i;
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (TetId t : m.tets())
    for (int k = 1; k < 4; ++k) parent[find(m.tet_vertices(t)[k].idx())] = find(m.tet_vertices(t)[0].idx());
  std::unordered_map<std::uint32_t, std::uint32_t> out;
  for (TetId t : m.tets()) out[t.idx()] = find(m.tet_vertices(t)[0].idx());
  return out;
}

std::vector<double> part_volumes(const TetMesh& m) {
  std::unordered_map<std::uint32_t, double> vol;
  for (const auto& [t, part] : tet_parts(m)) vol[part] += m.volume(TetId(t));
  std::vector<double> out;
  for (const auto& [r, v] : vol) out.push_back(v);
  std::sort(out.begin(), out.end());
  return out;
}

// Parts that share no vertex (a part held by one vertex or edge counts as attached).
std::size_t vertex_parts(const TetMesh& m) { return part_volumes(m).size(); }

// How a path cut an organ: parts (sharing no vertex) that hold tets more than `reach` on both
// sides of the path (`side`: signed, negative on one side), and specks (parts under 1e-4 of
// the volume: slivers cut off between two sheets), with their boxes. A speck inside a box of
// `own` (the uncut organ's own specks, which a path may cut in two) is not counted.
struct PathParts {
  std::size_t joined = 0, specks = 0;
  std::vector<std::pair<Vec3, Vec3>> speck_boxes;
};
PathParts path_parts(const TetMesh& m, const std::function<double(const Vec3&)>& side, double reach,
                     const std::vector<std::pair<Vec3, Vec3>>& own = {}) {
  const auto part_of = tet_parts(m);
  struct Part {
    double volume = 0;
    bool below = false, above = false;
    Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  };
  std::unordered_map<std::uint32_t, Part> parts;
  double total = 0;
  for (TetId t : m.tets()) {
    Vec3 c = Vec3::Zero();
    for (VertexId v : m.tet_vertices(t)) c += m.rest(v) / 4;
    Part& p = parts[part_of.at(t.idx())];
    p.volume += m.volume(t);
    total += m.volume(t);
    for (VertexId v : m.tet_vertices(t)) {
      p.lo = p.lo.cwiseMin(m.rest(v));
      p.hi = p.hi.cwiseMax(m.rest(v));
    }
    const double s = side(c);
    p.below = p.below || s < -reach;
    p.above = p.above || s > reach;
  }
  PathParts out;
  for (const auto& [r, p] : parts) {
    out.joined += p.below && p.above;
    if (!(p.volume < 1e-4 * total)) continue;
    const bool inside_own = std::any_of(own.begin(), own.end(), [&](const auto& b) {
      return (p.lo.array() >= b.first.array()).all() && (p.hi.array() <= b.second.array()).all();
    });
    if (inside_own) continue;
    ++out.specks;
    out.speck_boxes.push_back({p.lo, p.hi});
  }
  return out;
}

double tagged_area(const TetMesh& m) {
  double a = 0;
  for (const auto& f : m.boundary_faces())
    if (f.tag == kTagCut)
      a += 0.5 * (m.rest(f.vertices[1]) - m.rest(f.vertices[0])).cross(m.rest(f.vertices[2]) - m.rest(f.vertices[0])).norm();
  return 0.5 * a;  // one side
}

double mean_edge(const TetMesh& m) {
  double e = 0;
  std::size_t n = 0;
  for (TetId t : m.tets()) {
    const auto& tv = m.tet_vertices(t);
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j, ++n) e += (m.rest(tv[i]) - m.rest(tv[j])).norm();
  }
  return e / double(std::max<std::size_t>(n, 1));
}

struct Sweep {
  std::string name;
  TetMesh mesh;
  Vec3 a, b, d;
};

// Tets of the uncut mesh the whole motion's swept quad crosses (vertices strictly on both
// sides of its plane, and touching the quad): what "per crossed tet" counts.
std::size_t crossed_tets(const TetMesh& m, const Sweep& s) {
  const Vec3 a1 = s.a + s.d, b1 = s.b + s.d;
  const Vec3 n = (s.b - s.a).cross(b1 - s.a);
  std::size_t c = 0;
  for (TetId t : m.tets()) {
    bool plus = false, minus = false;
    for (VertexId v : m.tet_vertices(t)) {
      const double d = n.dot(m.rest(v) - s.a);
      plus |= d > 0;
      minus |= d < 0;
    }
    if (!(plus && minus)) continue;
    // Crossing points of the tet's edges with the plane, inside the quad (its two triangles).
    bool in = false;
    const auto& tv = m.tet_vertices(t);
    for (int i = 0; i < 4 && !in; ++i)
      for (int j = i + 1; j < 4 && !in; ++j) {
        const Vec3 p = m.rest(tv[i]), q = m.rest(tv[j]);
        const double dp = n.dot(p - s.a), dq = n.dot(q - s.a);
        if (dp * dq >= 0) continue;
        const Vec3 x = p + dp / (dp - dq) * (q - p);
        for (const auto& tri : {std::array<Vec3, 3>{s.a, s.b, b1}, std::array<Vec3, 3>{s.a, b1, a1}}) {
          const Vec3 e0 = tri[1] - tri[0], e1 = tri[2] - tri[0], w = x - tri[0];
          const Vec3 nn = e0.cross(e1);
          const double l1 = nn.dot(w.cross(e1)) / nn.squaredNorm(), l2 = nn.dot(e0.cross(w)) / nn.squaredNorm();
          in = in || (l1 >= 0 && l2 >= 0 && l1 + l2 <= 1);
        }
      }
    c += in;
  }
  return c;
}

// ---- 6 -------------------------------------------------------------------------------------
// Curved blade paths (issue 36): a vertical blade (z from -0.5 to 1.5) through a 4x2x1 box
// (cells 0.125) along a path in the xy-plane given as a function of t in [0, 1], in N steps,
// then finish(). The analytic part: the region the path closes off (its area times the height).
struct CurvedPath {
  std::string name;
  std::function<Vec3(double)> at;  // the path at t (z = 0)
  double part_volume;              // the part the path should detach (the smaller one)
};

std::vector<CurvedPath> curved_paths() {
  const double pi = std::acos(-1.0);
  std::vector<CurvedPath> out;
  // A half circle of radius 1 about (2.03, 0) (off the grid's planes), entering and leaving through y = 0 (straight in and
  // out over the first and last 5% of t).
  out.push_back({"arc", [pi](double t) {
                   if (t < 0.05) return Vec3(1.03, -0.2 + 4 * t, 0);
                   if (t > 0.95) return Vec3(3.03, 4 * (1 - t) - 0.2, 0);
                   const double a = pi * (1 - (t - 0.05) / 0.9);
                   return Vec3(2.03 + std::cos(a), std::sin(a), 0);
                 },
                 pi / 2});
  // An S: x = 2.03 + 0.5 sin(pi y), y from -0.2 to 2.2; the part right of it has area 3.94.
  out.push_back({"S", [pi](double t) {
                   const double y = -0.2 + 2.4 * t;
                   return Vec3(2.03 + 0.5 * std::sin(pi * y), y, 0);
                 },
                 3.94});
  // A 90-degree turn: up x = 1.53 from y = -0.2 to 1.03, then along y = 1.03 out through x = 4;
  // it cuts off the corner [1.53, 4] x [0, 1.03].
  out.push_back({"turn", [](double t) {
                   const double len = 1.23 + 2.67, s = t * len;
                   return s <= 1.23 ? Vec3(1.53, -0.2 + s, 0) : Vec3(1.53 + (s - 1.23), 1.03, 0);
                 },
                 2.47 * 1.03});
  return out;
}


// Tets of the uncut box whose edges cross the path (in the xy-plane: the blade spans the height).
std::size_t crossed_by_path(const TetMesh& m, const std::vector<Vec3>& path) {
  auto cross2 = [](const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b) {
    auto o = [](const Vec3& u, const Vec3& v, const Vec3& w) {
      return (v.x() - u.x()) * (w.y() - u.y()) - (v.y() - u.y()) * (w.x() - u.x());
    };
    return o(p, q, a) * o(p, q, b) < 0 && o(a, b, p) * o(a, b, q) < 0;
  };
  std::size_t c = 0;
  for (TetId t : m.tets()) {
    const auto& tv = m.tet_vertices(t);
    bool hit = false;
    for (int i = 0; i < 4 && !hit; ++i)
      for (int j = i + 1; j < 4 && !hit; ++j)
        for (std::size_t k = 0; k + 1 < path.size() && !hit; ++k)
          hit = cross2(m.rest(tv[i]), m.rest(tv[j]), path[k], path[k + 1]);
    c += hit;
  }
  return c;
}

void curved(bool quick, const std::string& only_case, int only_steps, double tolerance) {
  std::printf("# curved paths (a vertical blade along a path in N steps through a 4x2x1 box of cells 0.125, "
              "then finish(); the straight row is the same blade through the box in 100 steps)\n");
  std::printf("case,steps,tets_before,crossed,tets_after,added_per_crossed,over_straight,parts,part_volume,"
              "volume_error,min_dihedral,below_10deg_pct,ms_median,ms_p95,ms_max,ms_finish,open_over_swept\n");
  const TetMesh box = make_box(Vec3(4, 2, 1), {32, 16, 8});
  double straight_ratio = 0;
  auto run = [&](const std::string& name, const std::vector<Vec3>& pts, double expect, double tolerance) {
    TetMesh m = box;
    m.discard_change();
    const std::size_t crossed = crossed_by_path(m, pts);
    CutOptions opt;
    opt.provisional = g_provisional;
    opt.exact_volumes = g_exact_volumes;
    opt.path_tolerance = tolerance;
    Cutter cutter(m, opt);
    auto blade = [](const Vec3& p) { return BladeSegment{Vec3(p.x(), p.y(), -0.5), Vec3(p.x(), p.y(), 1.5)}; };
    cutter.start(blade(pts[0]));
    std::vector<double> ms;
    for (std::size_t k = 1; k < pts.size(); ++k) ms.push_back(cutter.advance(blade(pts[k])).ms);
    const double fin = cutter.finish().ms;
    const QualityRange q = quality_range(m, 10.0);
    const auto vols = part_volumes(m);
    if (const char* dir = std::getenv("INCISE_BENCH_CURVED_OUT")) {  // the cut meshes, to look at
      char file[96];
      std::snprintf(file, sizeof file, "/curved-%s-%zu%s.vtu", name.c_str(), pts.size() - 1, tolerance > 0 ? "" : "-exact");
      write_tet_mesh(m, std::string(dir) + file);
    }
    const double added = double(m.num_tets() - box.num_tets()) / double(std::max<std::size_t>(crossed, 1));
    // The area the blade swept inside the box: the polyline's length inside it times the height.
    double swept = 0;
    for (std::size_t k = 0; k + 1 < pts.size(); ++k) {
      Vec3 p = pts[k], q = pts[k + 1];
      // Clip the segment to the box's xy-rectangle [0, 4] x [0, 2] (parametric, Liang-Barsky).
      double t0 = 0, t1 = 1;
      const Vec3 d = q - p;
      for (int ax = 0; ax < 2; ++ax)
        for (const double lim : {0.0, ax == 0 ? 4.0 : 2.0}) {
          const double num = lim - p[ax], den = d[ax];
          const bool lower = lim == 0.0;
          if (den == 0) {
            if (lower ? p[ax] < lim : p[ax] > lim) t1 = -1;
            continue;
          }
          const double t = num / den;
          if (lower == (den > 0)) t0 = std::max(t0, t);
          else t1 = std::min(t1, t);
        }
      if (t1 > t0) swept += (t1 - t0) * d.norm();
    }
    if (name == "straight") straight_ratio = added;
    std::printf("%s%s,%zu,%zu,%zu,%zu,%.3f,%.3f,%zu,%.5f,%.5f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.4f\n", name.c_str(),
                tolerance > 0 ? "" : " (exact planes)", pts.size() - 1,
                box.num_tets(), crossed, m.num_tets(), added, straight_ratio > 0 ? added / straight_ratio : 0.0,
                vols.size(), vols.empty() ? 0.0 : vols[0], vols.empty() ? 1.0 : std::abs(vols[0] - expect) / expect,
                q.min_dihedral, 100.0 * double(q.below) / double(m.num_tets()), percentile(ms, 0.5),
                percentile(ms, 0.95), percentile(ms, 1.0), fin, tagged_area(m) / swept);
    std::fflush(stdout);
  };
  {
    std::vector<Vec3> pts;
    for (int k = 0; k <= 100; ++k) pts.push_back(Vec3(2.03, -0.2 + 2.4 * k / 100.0, 0));
    run("straight", pts, 3.94, tolerance);
  }
  for (const CurvedPath& c : curved_paths()) {
    if (!only_case.empty() && c.name.find(only_case) == std::string::npos) continue;
    std::vector<int> counts = {20, 100, 400};
    if (!quick) counts.push_back(4000);
    for (int n : counts) {
      if (only_steps > 0 && n != only_steps) continue;
      std::vector<Vec3> pts;
      for (int k = 0; k <= n; ++k) pts.push_back(c.at(double(k) / n));
      // The analytic volume of the path's inscribed polyline, not of the smooth path.
      double expect = c.part_volume;
      if (c.name != "S") {
        expect = 0;  // shoelace over the polyline's part inside the box, closed along the box's sides
        std::vector<Vec3> in;
        for (const Vec3& p : pts)
          if (p.y() >= 0 && p.x() <= 4) in.push_back(p);
        if (c.name == "turn") {
          in.insert(in.begin(), Vec3(1.53, 0, 0));
          in.push_back(Vec3(4, 1.03, 0));
          in.push_back(Vec3(4, 0, 0));
        }
        in.push_back(in.front());
        for (std::size_t k = 0; k + 1 < in.size(); ++k)
          expect += 0.5 * (in[k].x() * in[k + 1].y() - in[k + 1].x() * in[k].y());
        expect = std::abs(expect);
      }
      run(c.name, pts, expect, tolerance);
      // The cutter before issue 36: a new sheet wherever a step leaves the plane.
      if (n <= 100) run(c.name, pts, expect, 0);
    }
  }
}

// The arc and the S of curved() with their centres at random offsets against the grid (x in
// [-0.13, 0.12] of the rows above, a fixed seed): how many of the 48 drags stay in one part, and
// the quality they leave (figures: docs/cut.md#known-gaps).
void curved_offsets(double tolerance) {
  std::printf("# curved paths at 48 random offsets (arc and S, 8 each at 30, 100 and 400 steps, seed 1)\n");
  std::printf("case,drags,attached,extra_parts,min_dihedral_worst,below_10deg_pct_median,tets_after_median\n");
  const TetMesh box = make_box(Vec3(4, 2, 1), {32, 16, 8});
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> offset(-0.13, 0.12);
  const auto paths = curved_paths();
  for (int shape = 0; shape < 2; ++shape) {
    int attached = 0, extra = 0;
    double worst = 180;
    std::vector<double> below, tets;
    for (int steps : {30, 100, 400})
      for (int k = 0; k < 8; ++k) {
        const Vec3 dx(offset(rng), 0, 0);
        TetMesh m = box;
        CutOptions opt;
        opt.provisional = g_provisional;
        opt.exact_volumes = g_exact_volumes;
        opt.path_tolerance = tolerance;
        Cutter cutter(m, opt);
        auto blade = [](const Vec3& p) { return BladeSegment{Vec3(p.x(), p.y(), -0.5), Vec3(p.x(), p.y(), 1.5)}; };
        cutter.start(blade(paths[std::size_t(shape)].at(0) + dx));
        for (int i = 1; i <= steps; ++i) cutter.advance(blade(paths[std::size_t(shape)].at(double(i) / steps) + dx));
        cutter.finish();
        int large = 0, small = 0;  // the box's volume is 8; specks are slivers cut off at a crease
        for (double v : part_volumes(m)) (v > 1e-4 * 8 ? large : small) += 1;
        attached += large < 2;
        extra += small + std::max(large - 2, 0);
        const QualityRange q = quality_range(m, 10.0);
        worst = std::min(worst, q.min_dihedral);
        below.push_back(100.0 * double(q.below) / double(m.num_tets()));
        tets.push_back(double(m.num_tets()));
        if (const char* dir = std::getenv("INCISE_BENCH_CURVED_OUT"); dir && q.min_dihedral < 10) {
          char file[128];
          std::snprintf(file, sizeof file, "/offset-%s-%d-%+.4f.vtu", paths[std::size_t(shape)].name.c_str(), steps, dx.x());
          write_tet_mesh(m, std::string(dir) + file);
        }
        if (std::getenv("INCISE_BENCH_DRAGS"))  // each drag on stderr, to trace one
          std::fprintf(stderr, "%s steps %d dx %.17g: parts %d (specks %d), min dihedral %.4f, %zu below 10 deg\n",
                       paths[std::size_t(shape)].name.c_str(), steps, dx.x(), large, small, q.min_dihedral, q.below);
      }
    std::printf("%s,%zu,%d,%d,%.3f,%.3f,%.0f\n", paths[std::size_t(shape)].name.c_str(), below.size(), attached, extra,
                worst, percentile(below, 0.5), percentile(tets, 0.5));
    std::fflush(stdout);
  }
}

// The organ along curved paths at a tenth of an edge per step (the step-time goal of issue 36):
// a vertical blade spanning the organ's height following a half circle that enters and leaves
// through its low-y side, and an S across it in y, each against the straight sweep across the
// middle in the same step size. Step times (cut + default improvement), tets, parts. Then the
// half circle and the S at 10 offsets each (moved across the organ), a summary per shape: one
// drag's outcome at a crease is chance, the count over many is the figure.
void curved_organ(const TetMesh& organ, const std::string& name, double tolerance, const std::string& only_case,
                  int only_steps) {
  const RestBounds box = rest_bounds(organ);
  const Vec3 lo = box.lo, hi = box.hi;
  const Vec3 ext = hi - lo, c = 0.5 * (lo + hi);
  const double h = mean_edge(organ), pi = std::acos(-1.0);
  // An imaged organ may carry specks of its own (a tet alone): those are not the cut's.
  const PathParts own = path_parts(organ, [](const Vec3&) { return 0.0; }, h);
  const std::size_t own_specks = own.specks;
  std::printf("# curved paths on %s (%zu tets, mean edge %.3g): a vertical blade at 0.1, 0.3 and 0.05 of an edge "
              "per step, then finish()\n", name.c_str(), organ.num_tets(), h);
  std::printf("# joined: parts holding tissue more than an edge on both sides of the path (0: the path cut "
              "through); specks: parts under 1e-4 of the volume the cut made (the uncut organ has %zu of its "
              "own, not counted, nor their pieces)\n", own_specks);
  std::printf("case,steps,tets_after,parts,joined,specks,min_dihedral,below_10deg_pct,ms_median,ms_p95,ms_max,ms_finish\n");
  struct P {
    std::string name;
    std::function<Vec3(double)> at;
    double length;
    std::function<double(const Vec3&)> side;  // signed, across the path (in the xy plane)
  };
  // The three paths, their centre moved by (dx, dy).
  auto paths_at = [&](double dx, double dy) {
    const double r = 0.6 * ext.y(), y0 = lo.y() - 0.1 * ext.y() + dy, cx = c.x() + dx;
    const auto s_x = [=](double y) { return cx + 0.15 * ext.x() * std::sin(2 * pi * (y - y0) / (1.2 * ext.y())); };
    return std::vector<P>{
        {"straight", [=](double t) { return Vec3(cx + 0.013 * ext.x(), y0 + t * 1.2 * ext.y(), 0); }, 1.2 * ext.y(),
         [=](const Vec3& x) { return x.x() - (cx + 0.013 * ext.x()); }},
        {"arc", [=](double t) {
           const double a = pi * (1 - t);
           return Vec3(cx + r * std::cos(a), y0 + r * std::sin(a), 0);
         },
         pi * r, [=](const Vec3& x) { return std::hypot(x.x() - cx, x.y() - y0) - r; }},
        {"S", [=](double t) { return Vec3(s_x(y0 + t * 1.2 * ext.y()), y0 + t * 1.2 * ext.y(), 0); }, 1.3 * ext.y(),
         [=](const Vec3& x) { return x.x() - s_x(x.y()); }},
    };
  };
  struct Drag {
    int steps = 0;
    std::size_t tets = 0, parts = 0;
    PathParts pp;
    QualityRange q;
    std::vector<double> ms;
    double finish_ms = 0;
  };
  auto drag = [&](TetMesh m, const P& p, double per_step, const std::string& tag) {
    m.discard_change();
    CutOptions opt;
    opt.provisional = g_provisional;
    opt.exact_volumes = g_exact_volumes;
    opt.path_tolerance = tolerance;
    Cutter cutter(m, opt);
    Drag d;
    d.steps = int(std::ceil(p.length / (per_step * h)));
    auto blade = [&](const Vec3& q) {
      return BladeSegment{Vec3(q.x(), q.y(), lo.z() - 0.1 * ext.z()), Vec3(q.x(), q.y(), hi.z() + 0.1 * ext.z())};
    };
    cutter.start(blade(p.at(0)));
    for (int k = 1; k <= d.steps; ++k) {
      const CutStepReport r = cutter.advance(blade(p.at(double(k) / d.steps)));
      d.ms.push_back(r.ms);
      if (std::getenv("INCISE_BENCH_STEPS"))  // each step: ms, improvement ms, tets waiting, tets added
        std::fprintf(stderr, "step %d %.3f %.3f waiting %zu added %zu\n", k, r.ms, r.ms_improve, cutter.waiting_tets(),
                     r.change.added_tets.size());
    }
    d.finish_ms = cutter.finish().ms;
    d.tets = m.num_tets();
    if (const char* dir = std::getenv("INCISE_BENCH_CURVED_OUT"))  // the organ's cut meshes too
      write_tet_mesh(m, std::string(dir) + "/organ-" + p.name + "-" + std::to_string(d.steps) + tag + ".vtu");
    d.parts = vertex_parts(m);
    d.pp = path_parts(m, p.side, h, own.speck_boxes);
    d.q = quality_range(m, 10.0);
    return d;
  };
  // A tenth of an edge per step, then about a third and twice as many steps.
  const char* only_offset = std::getenv("INCISE_BENCH_OFFSET");  // one offset drag of each shape, to trace it
  for (const P& p : paths_at(0, 0))
    for (double per_step : {0.1, 0.3, 0.05}) {
      if (only_offset) continue;
      if (!only_case.empty() && p.name.find(only_case) == std::string::npos) continue;
      if (only_steps > 0 && int(std::ceil(p.length / (per_step * h))) != only_steps) continue;
      const Drag d = drag(organ, p, per_step, "");
      std::printf("%s,%d,%zu,%zu,%zu,%zu,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f\n", p.name.c_str(), d.steps, d.tets, d.parts,
                  d.pp.joined, d.pp.specks, d.q.min_dihedral, 100.0 * double(d.q.below) / double(d.tets),
                  percentile(d.ms, 0.5), percentile(d.ms, 0.95), percentile(d.ms, 1.0), d.finish_ms);
      std::fflush(stdout);
    }
  if (!only_case.empty() || only_steps > 0) return;
  std::printf("# the half circle and the S at 10 offsets each (centre moved by up to 0.26 of the organ's width and "
              "0.02 of its depth; a quarter and a tenth of an edge per step in turn)\n");
  std::printf("case,drags,joined,specks,min_dihedral_worst,below_10deg_pct_median,max_step_ms_median\n");
  for (int shape : {1, 2}) {
    std::size_t joined = 0, specks = 0;
    double worst = 180;
    std::vector<double> below, max_ms;
    for (int k = 0; k < 10; ++k) {
      if (only_offset && std::atoi(only_offset) != k) continue;
      const P p = paths_at((k - 2) * 0.037 * ext.x(), (k % 3 - 1) * 0.021 * ext.y())[std::size_t(shape)];
      const Drag d = drag(organ, p, k % 2 ? 0.1 : 0.25, "-offset" + std::to_string(k));
      if (std::getenv("INCISE_BENCH_DRAGS"))  // each drag on stderr, to trace one
        std::fprintf(stderr, "%s offset %d (%d steps): joined %zu, specks %zu, min dihedral %.4f\n", p.name.c_str(), k,
                     d.steps, d.pp.joined, d.pp.specks, d.q.min_dihedral);
      joined += d.pp.joined > 0;
      specks += d.pp.specks;
      worst = std::min(worst, d.q.min_dihedral);
      below.push_back(100.0 * double(d.q.below) / double(d.tets));
      max_ms.push_back(percentile(d.ms, 1.0));
    }
    std::printf("%s,10,%zu,%zu,%.3f,%.3f,%.1f\n", shape == 1 ? "arc" : "S", joined, specks, worst, percentile(below, 0.5),
                percentile(max_ms, 0.5));
    std::fflush(stdout);
  }
}

// A deforming organ (issue 36): held on its low-x side (15% of its length), a probe pressing
// the top of its far end down by `push` of its height over frames 0-50, and a blade across it
// going 60% down through its middle over frames 10-50, one step before each frame's static
// corotational solve, then finish(). The cut's sheet in the rest shape (material_frame, the
// default) against each step cut in the current shape; the quality of the result and the
// boundary's sharpest angle after the cut (a crease the blade did not make shows there).
void deformed(const TetMesh& organ_in, const std::string& name, bool quick, double path_tolerance) {
  TetMesh organ = organ_in;
  {
    // Imaged organs carry specks: the largest face-connected part alone (a free speck would make
    // the static solve singular).
    const TetComponents comps = tet_components(organ);
    const int keep = int(std::max_element(comps.sizes.begin(), comps.sizes.end()) - comps.sizes.begin());
    for (TetId t : organ.tets())
      if (comps.of_tet[t.idx()] != keep) organ.remove_tet(t);
    organ.compact();
  }
  organ.discard_change();
  const RestBounds box = rest_bounds(organ);
  const Vec3 lo = box.lo, hi = box.hi;
  const Vec3 size = hi - lo, c = 0.5 * (lo + hi);
  const auto b0 = smallest_boundary_angle(organ);
  const QualityRange q0 = quality_range(organ, 10.0);
  std::printf("# deformed organ (%s, %zu tets, uncut: smallest dihedral %.3f, sharpest boundary angle %.2f deg): "
              "held at low x, probe pushing the far end's top down, blade 60%% down through the middle over "
              "frames 10-50 on the current shape, corotational static\n",
              name.c_str(), organ.num_tets(), q0.min_dihedral, b0 ? b0->degrees : 0.0);
  // Issue 36's goal for these rows: smallest dihedral >= min(10, half the uncut body's sharpest
  // boundary angle), under 1% below 10 degrees, and no crease the blade did not make (the
  // boundary's sharpest angle after the cut at least 20 degrees).
  const double goal = std::min(10.0, 0.5 * (b0 ? b0->degrees : 0.0));
  std::printf("# goal: min dihedral >= %.2f deg (min(10, half the sharpest boundary angle)), < 1%% below 10 deg, "
              "boundary angle after >= 20 deg\n", goal);
  std::printf("push,frame,tets_after,min_dihedral,below_10deg_pct,boundary_angle_after,cut_area,ms_step_median,"
              "ms_step_p95,max_displacement,meets_goal\n");
  std::vector<double> pushes = {0.0, 0.05, 0.15, 0.30};
  if (quick) pushes = {0.0, 0.15};
  for (double push : pushes)
    for (bool material : {true, false}) {
      TetMesh m = organ;
      FemSimulationOptions o;
      o.kind = FemKind::Corotational;
      o.cg.tolerance = 1e-6;
      FemSimulation fem(m, MaterialTable(Material{5e3, 0.4, 1}), o);
      std::vector<VertexId> probe;
      for (VertexId v : m.vertices()) {
        const Vec3 p = m.rest(v);
        if (p.x() <= lo.x() + 0.15 * size.x()) fem.fix(v);
        else if (p.x() >= hi.x() - 0.15 * size.x() && p.z() >= hi.z() - 0.25 * size.z()) probe.push_back(v);
      }
      CutOptions opt;
      opt.provisional = g_provisional;
      opt.exact_volumes = g_exact_volumes;
      opt.material_frame = material;
      opt.path_tolerance = path_tolerance;
      Cutter cutter(m, opt);
      const Vec3 a(c.x() + 0.013 * size.x(), lo.y() - 0.1 * size.y(), hi.z() + 0.05 * size.z());
      const Vec3 b(c.x() + 0.013 * size.x(), hi.y() + 0.1 * size.y(), hi.z() + 0.05 * size.z());
      const Vec3 down(0, 0, -0.65 * size.z());
      std::vector<double> ms;
      double max_disp = 0;
      auto current = [&](VertexId v) { return Vec3(m.rest(v) + fem.displacement().segment<3>(3 * v.idx())); };
      for (int frame = 0; frame <= 55; ++frame) {
        const double ramp = std::min(1.0, frame / 50.0);
        for (VertexId v : probe)
          if (m.is_alive(v)) fem.prescribe(v, Vec3(0, 0, -push * size.z() * ramp));
        if (frame == 10) cutter.start({a, b});
        if (frame > 10 && frame <= 50) {
          const Vec3 off = down * (double(frame - 10) / 40.0);
          CutStepReport r = cutter.advance({a + off, b + off}, current);
          ms.push_back(r.ms);
          fem.apply(r.change);
          if (frame == 50) fem.apply(cutter.finish(current).change);
        }
        fem.step();
      }
      for (VertexId v : m.vertices()) max_disp = std::max(max_disp, fem.displacement().segment<3>(3 * v.idx()).norm());
      const QualityRange q = quality_range(m, 10.0);
      const auto b1 = smallest_boundary_angle(m);
      if (const char* dir = std::getenv("INCISE_BENCH_DEFORMED_OUT")) {  // the cut meshes, to look at
        char file[64];
        std::snprintf(file, sizeof file, "/deformed-%02d-%s.vtu", int(std::lround(100 * push)), material ? "rest" : "current");
        write_tet_mesh(m, std::string(dir) + file);
      }
      const double below_pct = 100.0 * double(q.below) / double(m.num_tets()), crease = b1 ? b1->degrees : 0.0;
      const bool smallest_ok = q.min_dihedral >= goal, share_ok = below_pct < 1, crease_ok = crease >= 20;
      std::string meets;
      for (const auto& [ok, what] : {std::pair{smallest_ok, "smallest no"}, {share_ok, "share no"}, {crease_ok, "crease no"}})
        if (!ok) meets += (meets.empty() ? "" : " / ") + std::string(what);
      std::printf("%.2f,%s,%zu,%.3f,%.3f,%.2f,%.4g,%.3f,%.3f,%.4g,%s\n", push, material ? "rest" : "current", m.num_tets(),
                  q.min_dihedral, below_pct, crease, tagged_area(m), percentile(ms, 0.5), percentile(ms, 0.95), max_disp,
                  meets.empty() ? "yes" : meets.c_str());
      std::fflush(stdout);
    }
}

void progressive(const TetMesh& organ, const std::string& name, bool quick, const std::string& only_case,
                 int only_steps) {
  std::printf("# progressive (one blade motion in N steps, then finish(): growth per crossed tet, area, parts, "
              "quality and step times against the single step; default options)\n");
  std::printf("case,steps,step_over_edge,tets_before,crossed,tets_after,added_per_crossed,cut_area,area_over_1step,"
              "parts,min_dihedral,below_10deg,ms_median,ms_p95,ms_max,ms_finish,ms_improve_median,ms_improve_p95,"
              "mesh_fingerprint,ms_finish_improve,open_share_min\n");
  std::vector<Sweep> cases;
  cases.push_back({"box4x1x1 partial", make_box(Vec3(4, 1, 1), {16, 4, 4}), Vec3(2.03, -0.5, 1.1), Vec3(2.03, 1.5, 1.1),
                   Vec3(0, 0, -0.6)});
  cases.push_back({"box4x1x1 through", make_box(Vec3(4, 1, 1), {16, 4, 4}), Vec3(2.03, -0.5, 1.1), Vec3(2.03, 1.5, 1.1),
                   Vec3(0, 0, -1.3)});
  cases.push_back({"box10^3 oblique", make_box(Vec3(10, 10, 10), {10, 10, 10}), Vec3(-1, -1, 11.3), Vec3(11, 12.1, 10.2),
                   Vec3(0.9, -1.2, -13)});
  {
    // Through the organ's middle, top to bottom, across its whole width.
    const RestBounds box = rest_bounds(organ);
    const Vec3 lo = box.lo, hi = box.hi;
    const Vec3 ext = hi - lo, c = 0.5 * (lo + hi);
    const double x = c.x() + 0.013 * ext.x();
    cases.push_back({name + " through", organ, Vec3(x, lo.y() - 0.1 * ext.y(), hi.z() + 0.05 * ext.z()),
                     Vec3(x + 0.02 * ext.x(), hi.y() + 0.1 * ext.y(), hi.z() + 0.05 * ext.z()), Vec3(0, 0, -1.1 * ext.z())});
  }
  for (Sweep& s : cases) {
    if (!only_case.empty() && s.name.find(only_case) == std::string::npos) continue;
    s.mesh.discard_change();
    const std::size_t crossed = crossed_tets(s.mesh, s);
    const double h = mean_edge(s.mesh);
    std::vector<int> counts = {1, 10, 40, 400};
    if (!quick && s.name.rfind("box4", 0) == 0) counts.push_back(4000);
    // One tenth of an edge per step (a hand's motion at 60 Hz).
    const int tenth = int(std::ceil(s.d.norm() / (0.1 * h)));
    counts.push_back(tenth);
    double area1 = 0;
    struct Variant {
      int steps;
      bool improve, provisional;
    };
    std::vector<Variant> variants;
    for (int n : counts) variants.push_back({n, true, false});
    variants.push_back({tenth, false, false});  // the cut's own share, without the improvement
    variants.push_back({tenth, true, true});    // with the provisional pieces (open up to the blade)
    // The box4 cases: a blade across the whole width going straight down from 0.1 above the
    // top, so the area it has swept inside the box is its depth: open_share_min is the least
    // share of that open after a step once the blade is an edge deep (docs/cut.md#the-opening).
    const bool box4 = s.name.rfind("box4", 0) == 0;
    for (const auto& [n, improve, provisional] : variants) {
      if (only_steps > 0 && n != only_steps) continue;
      TetMesh m = s.mesh;
      CutOptions opt;
      opt.provisional = g_provisional;
      opt.exact_volumes = g_exact_volumes;
      opt.improve = improve;
      opt.provisional = provisional || g_provisional;
      opt.exact_volumes = g_exact_volumes;
      Cutter cutter(m, opt);
      cutter.start({s.a, s.b});
      std::vector<double> ms, ms_imp;
      double open_min = 1e300;
      for (int k = 1; k <= n; ++k) {
        const Vec3 off = s.d * (double(k) / n);
        const CutStepReport r = cutter.advance({s.a + off, s.b + off});
        ms.push_back(r.ms);
        ms_imp.push_back(r.ms_improve);
        const double depth = std::min(1.0, 1.0 - (s.a + off).z());
        if (box4 && depth >= h) open_min = std::min(open_min, tagged_area(m) / depth);
      }
      const CutStepReport fin_rep = cutter.finish();
      const double fin = fin_rep.ms;
      const QualityRange q = quality_range(m, 10.0);
      const std::size_t below10 = q.below;
      const double area = tagged_area(m);
      if (n == 1) area1 = area;
      std::printf("%s%s,%d,%.3f,%zu,%zu,%zu,%.2f,%.4g,%.4f,%zu,%.3f,%zu,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%016llx,%.3f,%s\n", s.name.c_str(),
                  !improve ? " (no improve)" : provisional ? " (provisional)" : "", n,
                  s.d.norm() / n / h, s.mesh.num_tets(), crossed, m.num_tets(),
                  double(m.num_tets() - s.mesh.num_tets()) / double(std::max<std::size_t>(crossed, 1)), area,
                  area / area1, vertex_parts(m), q.min_dihedral, below10, percentile(ms, 0.5), percentile(ms, 0.95),
                  percentile(ms, 1.0), fin, percentile(ms_imp, 0.5), percentile(ms_imp, 0.95),
                  (unsigned long long)fingerprint(m), fin_rep.ms_improve,
                  open_min < 1e300 ? std::to_string(open_min).c_str() : "-");
      std::fflush(stdout);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, with_1m = true;
  std::string organ_path = std::string(INCISE_SOURCE_DIR) + "/samples/liver.msh", only, only_case;
  int only_steps = 0;
  double path_tolerance = CutOptions{}.path_tolerance;  // the curved rows' CutOptions::path_tolerance
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--quick")) quick = true;
    else if (!std::strcmp(argv[i], "--no-1m")) with_1m = false;
    else if (!std::strcmp(argv[i], "--provisional")) g_provisional = true;
    else if (!std::strcmp(argv[i], "--no-exact-volumes")) g_exact_volumes = false;
    else if (!std::strcmp(argv[i], "--only") && i + 1 < argc) only = argv[++i];
    else if (!std::strcmp(argv[i], "--case") && i + 1 < argc) only_case = argv[++i];
    else if (!std::strcmp(argv[i], "--steps") && i + 1 < argc) only_steps = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--path-tolerance") && i + 1 < argc) path_tolerance = std::atof(argv[++i]);
    else if (argv[i][0] == '-') {
      std::fprintf(stderr, "usage: bench_cut [--quick] [--no-1m] [--provisional] [--no-exact-volumes] [--only step|quality|snap|beam|progressive|curved|curved-organ|deformed] "
                           "[--case NAME_PART] [--steps N] [--path-tolerance X] [ORGAN]\n");
      return 1;
    } else organ_path = argv[i];
  }
  auto want = [&](const char* s) { return only.empty() || only == s; };
  if (want("step")) step_to_solver_ready(quick, with_1m);
  TetMesh organ = read_tet_mesh(organ_path);
  organ.discard_change();
  const std::string name = std::filesystem::path(organ_path).filename().string();
  if (want("quality")) quality_after_cuts(organ, name, quick);
  if (want("snap")) snap_trade(organ);
  if (want("beam")) beam_ratio(quick);
  if (want("progressive")) progressive(organ, name, quick, only_case, only_steps);
  if (want("curved")) curved(quick, only_case, only_steps, path_tolerance);
  if (want("curved") && only_case.empty() && only_steps == 0) curved_offsets(path_tolerance);
  if (only == "curved-organ") curved_organ(organ, name, path_tolerance, only_case, only_steps);  // by name: give it an imaged organ
  if (only == "deformed") deformed(organ, name, quick, path_tolerance);  // by name only: it needs an imaged organ (ORGAN)
  return 0;
}
