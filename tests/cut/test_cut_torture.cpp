// Torture: thousands of random progressive blade steps over boxes, balls and organ meshes
// (image- and surface-meshed samples) at scales 1e-6, 1 and 1e6, with random snap thresholds,
// rotating blades, curved paths and axis-aligned blades through vertex layers. After EVERY step: validate()
// (incidence, orientation, closed manifold boundary) and every label's rest volume.
// INCISE_TORTURE_STEPS sets the total (default 10000; the sanitizer run uses fewer).
#include <catch2/catch.hpp>

#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <random>

#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "tests/cut/cut_checks.h"
#include "testing/mesh_edits.h"
#include "testing/draws.h"

using namespace incise;
using namespace incise::testing;

namespace {

struct Case {
  std::string name;
  TetMesh mesh;
};

void scale_mesh(TetMesh& m, double s) {
  for (VertexId v : m.vertices()) m.set_rest(v, m.rest(v) * s);
}

std::vector<Case> torture_meshes() {
  std::vector<Case> out;
  TetMesh box = make_box(Vec3(1, 0.8, 0.6), {6, 5, 4});
  out.push_back({"box", box});
  TetMesh jb = make_box(Vec3(1, 1, 1), {5, 5, 5});
  testing::jitter(jb, 0.3, 17);
  out.push_back({"jittered box", jb});
  out.push_back({"ball", make_ellipsoid(Vec3(1, 0.7, 0.5), 4)});
  for (const char* f : {"liver.msh", "elephant.msh"}) {
    const std::string path = std::string(INCISE_SOURCE_DIR) + "/samples/" + f;
    if (std::filesystem::exists(path)) out.push_back({f, read_tet_mesh(path)});
  }
  const std::size_t n = out.size();
  for (std::size_t i = 0; i < n; ++i)
    for (double s : {1e-6, 1e6}) {
      Case c{out[i].name + " x" + (s < 1 ? "1e-6" : "1e6"), out[i].mesh};
      scale_mesh(c.mesh, s);
      out.push_back(std::move(c));
    }
  for (Case& c : out) c.mesh.discard_change();
  return out;
}

}  // namespace

TEST_CASE("torture: random progressive cuts keep every invariant after every step", "[cut][torture][long]") {
  const char* env = std::getenv("INCISE_TORTURE_STEPS");
  const long total = env ? std::atol(env) : 10000;
  std::vector<Case> cases = torture_meshes();
  std::mt19937 rng(std::getenv("INCISE_TORTURE_SEED") ? unsigned(std::atol(std::getenv("INCISE_TORTURE_SEED"))) : 2026u);
  std::uniform_real_distribution<double> u01(0, 1);
  auto unit = [&] {
    std::normal_distribution<double> nd;
    Vec3 d = draw_vec3(nd, rng);
    return d.normalized();
  };
  long steps = 0, sequences = 0, through = 0, area_checks = 0, exact_area = 0, short_area = 0;
  long curved_checks = 0, curved_close = 0;  // curved walks on a fresh box: opened against swept
  std::size_t ci = 0;
  while (steps < total) {
    Case& base = cases[ci++ % cases.size()];
    TetMesh m = base.mesh;  // every few sequences start again from the uncut mesh
    Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
    std::vector<Vec3> layer;
    for (VertexId v : m.vertices()) {
      lo = lo.cwiseMin(m.rest(v));
      hi = hi.cwiseMax(m.rest(v));
      // Interior vertices: a blade through one of them lies in a layer of vertices (boxes).
      if (layer.size() < 64 && m.incident_tets(v).size() >= 12) {
        bool interior = true;
        for (TetId t : m.incident_tets(v))
          for (int f = 0; f < 4; ++f) interior = interior && m.neighbor(t, f).is_valid();
        if (interior) layer.push_back(m.rest(v));
      }
    }
    const double diag = (hi - lo).norm();
    const auto vol0 = label_volumes(m);
    double moved = 0;  // label volume moved by tolerance-mode contractions (reported, checked small)
    for (int seq = 0; seq < 4 && steps < total; ++seq, ++sequences) {
      CutOptions opt;
      // Half the cuts run the local improvement, bounded by work (not wall time) so that the
      // run is reproducible.
      opt.improve = rng() % 2 == 0;
      opt.improve_budget_ms = 0;
      opt.improve_options.max_work = 100;
      opt.finish_improve_work = 100;
      // Every fourth sequence cuts the tets the blade is in provisionally and takes them back at
      // the next step (CutOptions::provisional): the invariants hold after every step with the
      // pieces in place too. (Chosen by the count, not the generator: the draws stay the same.)
      opt.provisional = sequences % 4 == 3;
      const double snaps[] = {0.0, 0.02, 0.1, 0.3};
      opt.snap = snaps[rng() % 4];
      Cutter cutter(m, opt);
      const Vec3 c = lo + draw_vec3(u01, rng).cwiseProduct(hi - lo);
      Vec3 dir, sweep;
      Vec3 centre = c;
      if (!layer.empty() && rng() % 3 == 0) {
        // Axis-aligned blade through a vertex layer, swept along another axis.
        const int a = int(rng() % 3), b = (a + 1 + int(rng() % 2)) % 3;
        dir = Vec3::Unit(a);
        sweep = Vec3::Unit(b);
        const Vec3& p = layer[rng() % layer.size()];
        centre = p;  // through an existing vertex: its layer is a plane of vertices in a box
      } else {
        dir = unit();
        sweep = unit();
        sweep = (sweep - sweep.dot(dir) * dir).normalized();
      }
      const double len = diag * (0.3 + 1.2 * u01(rng));
      // A third of the cuts away from vertex layers walk a curved path: the motion turns about
      // the blade by up to 90 degrees (either way) over the cut, in up to 30 steps (curved
      // paths, CutOptions::path_tolerance).
      const bool curved = centre == c && rng() % 3 == 0;
      const double bend = curved ? 1.6 * (u01(rng) - 0.5) : 0.0;
      const int nsteps = curved ? 4 + int(rng() % 27) : 2 + int(rng() % 7);
      const double travel = diag * (0.2 + 0.9 * u01(rng));
      const double turn = (rng() % 2 || curved) ? 0.0 : 0.4 * (u01(rng) - 0.5);
      const Vec3 axis = unit();
      Vec3 start = centre - 0.5 * travel * sweep;
      cutter.start({start - 0.5 * len * dir, start + 0.5 * len * dir});
      // A straight sweep on a fresh box must open exactly what it swept inside the box, however
      // it was sliced into steps (checked after finish(); rotating blades cut a bent surface).
      const bool check_area = seq == 0 && turn == 0.0 && !curved && opt.snap <= 0.02 && base.name.rfind("box", 0) == 0;
      Vec3 walk = start;  // a curved path's blade centre
      // A curved walk on a fresh box: the area it swept inside the box, step by step (the blade
      // keeps its direction; each step sweeps a parallelogram).
      const bool check_curved = seq == 0 && curved && opt.snap <= 0.02 && base.name.rfind("box", 0) == 0;
      double curved_swept = 0;
      const double area_before = check_area || check_curved ? tagged_area(m, kTagCut) : 0;
      for (int s = 1; s <= nsteps && steps < total; ++s, ++steps) {
        const double f = double(s) / nsteps;
        const Vec3 d2 = Eigen::AngleAxisd(turn * f, axis) * dir;
        walk += (travel / nsteps) * (Eigen::AngleAxisd(bend * f, dir) * sweep);
        const Vec3 mid = curved ? walk : Vec3(start + f * travel * sweep);
        if (check_curved) {
          const Vec3 prev = walk - (travel / nsteps) * (Eigen::AngleAxisd(bend * f, dir) * sweep);
          curved_swept += swept_area_in_box(prev - 0.5 * len * dir, prev + 0.5 * len * dir, mid - prev, lo, hi);
        }
        INFO(base.name << " sequence " << sequences << " step " << s << " snap " << opt.snap);
        const CutStepReport r = cutter.advance({mid - 0.5 * len * d2, mid + 0.5 * len * d2});
        moved += r.improve.volume_change;
        check_cut_invariants(m, vol0, 1e-9, moved);
        check_fragments(m, r);
        through += !r.fragments.empty();
      }
      const CutStepReport fin = cutter.finish();
      moved += fin.improve.volume_change;
      check_cut_invariants(m, vol0, 1e-9, moved);
      check_fragments(m, fin);
      if (check_curved && curved_swept > 1e-3 * diag * diag) {
        // Counted, not required: a curved path is cut as planar sheets within path_tolerance of
        // the blade (docs/cut.md#curved-paths), so the opened area follows the path to a few %.
        const double opened = 0.5 * (tagged_area(m, kTagCut) - area_before);
        curved_close += std::abs(opened - curved_swept) <= 0.03 * curved_swept;
        ++curved_checks;
      }
      if (check_area) {
        const double swept = swept_area_in_box(start - 0.5 * len * dir, start + 0.5 * len * dir, travel * sweep, lo, hi);
        const double opened = 0.5 * (tagged_area(m, kTagCut) - area_before);
        const bool in_layer = !(centre == c);  // the blade lies in a plane of mesh faces
        INFO(base.name << " sequence " << sequences << ": swept area inside " << swept << ", opened " << opened << ", "
                       << nsteps << " steps, snap " << opt.snap << ", in a vertex layer " << in_layer);
        // Counted, not required here: test_cut_progressive's "[!mayfail]" case holds the known
        // gaps (docs/cut.md) to the exact area; this run's validity checks above stay strict.
        if (swept > 1e-3 * diag * diag) {
          (std::abs(opened - swept) <= 0.01 * swept ? exact_area : short_area)++;
        }
        ++area_checks;
      }
    }
    // Tolerance-mode contractions move the boundary by hairs (at most 1% of an edge each);
    // over the ~500 cuts a mesh gets here they add up to about 1e-4 of its volume.
    double total = 0;
    for (const auto& [l, v] : vol0) total += v;
    CHECK(moved <= 1e-3 * total);
  }
  CHECK(steps >= total);
  CHECK(area_checks > 0);
  WARN("torture: " << steps << " steps, " << sequences << " cuts, " << through << " steps detached a part, "
                    << area_checks << " straight box cuts checked, " << exact_area << " opened their swept area to 1%, "
                    << short_area << " did not; " << curved_checks << " curved walks on a fresh box checked, "
                    << curved_close << " opened their swept area to 3%");
}
