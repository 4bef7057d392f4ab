// Progressive cutting at interactive step sizes: the same blade motion sliced into 1 to 4000
// steps gives the same cut (area opened, parts, tet count), a grazing blade changes nothing,
// and the result is deterministic.
#include <catch2/catch.hpp>

#include <cmath>
#include <numeric>
#include <random>

#include "cut/cutter.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "quality/metrics.h"
#include "tests/cut/cut_checks.h"
#include "testing/draws.h"

using namespace incise;
using namespace incise::testing;

namespace {

// Parts that share no vertex (tets touching at a vertex or an edge are one part: physically
// still attached there).
std::size_t vertex_parts(const TetMesh& m) {
  std::vector<std::uint32_t> parent(m.vertex_capacity());
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (TetId t : m.tets()) {
    const auto& tv = m.tet_vertices(t);
    for (int k = 1; k < 4; ++k) parent[find(tv[std::size_t(k)].idx())] = find(tv[0].idx());
  }
  std::size_t n = 0;
  for (VertexId v : m.vertices()) n += !m.incident_tets(v).empty() && find(v.idx()) == v.idx();
  return n;
}

struct Outcome {
  std::size_t tets = 0, parts = 0;
  double area = 0;  // cut-tagged area, one side
  double min_dihedral = 0;
};

// The blade a-b moves by d in `steps` equal steps (as `incise cut --steps` does), then finish().
Outcome sweep(TetMesh m, const Vec3& a, const Vec3& b, const Vec3& d, int steps, CutOptions opt, bool check_each = false) {
  const auto vol0 = label_volumes(m);
  Cutter cutter(m, opt);
  cutter.start({a, b});
  double moved = 0;  // label volume the improvement's tolerance-mode contractions moved
  for (int k = 1; k <= steps; ++k) {
    const Vec3 off = d * (double(k) / steps);
    moved += cutter.advance({a + off, b + off}).improve.volume_change;
    if (check_each) check_cut_invariants(m, vol0, 1e-9, moved);
  }
  moved += cutter.finish().improve.volume_change;
  check_cut_invariants(m, vol0, 1e-9, moved);
  const QualityRange q = quality_range(m);
  return {m.num_tets(), vertex_parts(m), 0.5 * tagged_area(m, kTagCut), q.min_dihedral};
}

CutOptions no_improve() {
  CutOptions o;
  o.improve = false;
  return o;
}

TetMesh box4() {
  TetMesh m = make_box(Vec3(4, 1, 1), {16, 4, 4});
  m.discard_change();
  return m;
}

}  // namespace

TEST_CASE("progressive: a partial cut opens the swept area whatever the step count", "[cut][progressive]") {
  // The case: box 4x1x1, 0.25 cells, blade 0.6 down from above the top (0.5 inside).
  const Vec3 a(2.03, -0.5, 1.1), b(2.03, 1.5, 1.1), d(0, 0, -0.6);
  for (bool improve : {false, true}) {
    CutOptions o = improve ? CutOptions{} : no_improve();
    const Outcome one = sweep(box4(), a, b, d, 1, o);
    CHECK(one.area == Approx(0.5).epsilon(0.01));
    CHECK(one.parts == 1);
    for (int steps : {10, 40, 400, 4000}) {
      INFO("improve " << improve << ", steps " << steps);
      const Outcome r = sweep(box4(), a, b, d, steps, o, steps == 40);
      CHECK(r.area == Approx(0.5).epsilon(0.01));
      CHECK(r.parts == 1);
      CHECK(std::abs(double(r.tets) - double(one.tets)) <= 0.1 * double(one.tets));
    }
  }
}

TEST_CASE("progressive: a through-cut separates whatever the step count", "[cut][progressive]") {
  const Vec3 a(2.03, -0.5, 1.1), b(2.03, 1.5, 1.1), d(0, 0, -1.3);
  const std::size_t tets0 = box4().num_tets();
  const Outcome one = sweep(box4(), a, b, d, 1, {});
  CHECK(one.parts == 2);
  CHECK(one.area == Approx(1.0).epsilon(0.01));
  for (int steps : {20, 100, 400}) {
    INFO("steps " << steps);
    const Outcome r = sweep(box4(), a, b, d, steps, {});
    CHECK(r.parts == 2);
    CHECK(r.area == Approx(1.0).epsilon(0.01));
    CHECK(std::abs(double(r.tets) - double(one.tets)) <= 0.1 * double(one.tets));
    // A plane adds a handful of tets per tet it crosses, not a number growing with the steps.
    CHECK(double(r.tets) < 2.0 * double(tets0));
  }
}

TEST_CASE("progressive: an oblique through-cut of a cube is step-count independent", "[cut][progressive]") {
  auto cube = [] {
    TetMesh m = make_box(Vec3(10, 10, 10), {10, 10, 10});
    m.discard_change();
    return m;
  };
  // A tilted blade plane (normal not along any axis) swept through the whole cube.
  const Vec3 a(-1, -1, 11.3), b(11, 12.1, 10.2), d(0.9, -1.2, -13);
  const Outcome one = sweep(cube(), a, b, d, 1, {});
  CHECK(one.parts == 2);
  for (int steps : {10, 100}) {
    INFO("steps " << steps);
    const Outcome r = sweep(cube(), a, b, d, steps, {});
    CHECK(r.parts == 2);
    CHECK(r.area == Approx(one.area).epsilon(0.01));
    CHECK(std::abs(double(r.tets) - double(one.tets)) <= 0.1 * double(one.tets));
  }
}

TEST_CASE("progressive: tiny steps with any snap threshold leave no swept face shut", "[cut][progressive]") {
  const Vec3 a(2.03, -0.5, 1.1), b(2.03, 1.5, 1.1), d(0, 0, -0.6);
  for (double snap : {0.0, 0.05, 0.3, 0.49}) {
    CutOptions o = no_improve();
    o.snap = snap;
    INFO("snap " << snap);
    // 600 steps: 1/250 of an edge per step.
    const Outcome r = sweep(box4(), a, b, d, 600, o);
    CHECK(r.area == Approx(0.5).epsilon(0.01));
    const Outcome t = sweep(box4(), a, b, Vec3(0, 0, -1.3), 600, o);
    CHECK(t.parts == 2);
  }
}

TEST_CASE("progressive: a blade that grazes a face or misses the body changes nothing", "[cut][progressive]") {
  for (const auto& [a, b, d] : {std::tuple{Vec3(-1, 0, 1), Vec3(5, 0, 1), Vec3(0, 0.5, 0)},    // in the top face
                                std::tuple{Vec3(-1, 0, 3), Vec3(5, 0, 3), Vec3(0, 0.5, 0)},    // above the body
                                std::tuple{Vec3(-1, 0, 1), Vec3(5, 0, 1), Vec3(0, 0, 0.5)}}) {  // touches the top edge
    for (int steps : {1, 5}) {
      TetMesh m = box4();
      const TetMesh before = m;
      Cutter cutter(m);
      cutter.start({a, b});
      for (int k = 1; k <= steps; ++k) {
        const CutStepReport r = cutter.advance({a + d * (double(k) / steps), b + d * (double(k) / steps)});
        CHECK(r.change.empty());
      }
      CHECK(cutter.finish().change.empty());
      REQUIRE(m.num_tets() == before.num_tets());
      REQUIRE(m.num_vertices() == before.num_vertices());
      bool same = true;
      for (TetId t : m.tets()) same = same && m.tet_vertices(t) == before.tet_vertices(t);
      for (VertexId v : m.vertices()) same = same && m.rest(v) == before.rest(v);
      CHECK(same);
    }
  }
}

TEST_CASE("progressive: two runs of the same cut give the same mesh", "[cut][progressive]") {
  const Vec3 a(2.03, -0.5, 1.1), b(2.03, 1.5, 1.1), d(0, 0, -0.8);
  auto run = [&] {
    TetMesh m = box4();
    Cutter cutter(m);  // default options: the improvement's budget counts operations
    cutter.start({a, b});
    for (int k = 1; k <= 30; ++k) cutter.advance({a + d * (k / 30.0), b + d * (k / 30.0)});
    cutter.finish();
    return m;
  };
  const TetMesh m1 = run(), m2 = run();
  REQUIRE(m1.num_tets() == m2.num_tets());
  REQUIRE(m1.num_vertices() == m2.num_vertices());
  bool same = true;
  for (TetId t : m1.tets()) same = same && m2.is_alive(t) && m1.tet_vertices(t) == m2.tet_vertices(t);
  for (VertexId v : m1.vertices()) same = same && m1.rest(v) == m2.rest(v);
  CHECK(same);
}

// Random straight cuts of a box, each in a few steps then finish(), must open exactly the area
// they swept inside it. Five of these 60 used to open 63% to 96% of it (the same in one step and
// with snap 0): cut 13's corners inside the box left chords, cut-surface edges between two rim
// vertices, whose faces stayed shut and closed their neighbours in turn (cut/separate.cpp).
TEST_CASE("progressive: random straight cuts of a box open exactly their swept area", "[cut][progressive]") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u01(0, 1);
  std::normal_distribution<double> nd;
  auto unit = [&] { return draw_vec3(nd, rng).normalized(); };
  const Vec3 lo(0, 0, 0), hi(1, 0.8, 0.6);
  int exact = 0, total = 0;
  for (int i = 0; i < 60; ++i) {
    TetMesh m = make_box(hi, {6, 5, 4});
    m.discard_change();
    const Vec3 dir = unit();
    Vec3 sweep = unit();
    sweep = (sweep - sweep.dot(dir) * dir).normalized();
    const double diag = hi.norm(), len = diag * (0.3 + 1.2 * u01(rng)), travel = diag * (0.2 + 0.9 * u01(rng));
    const Vec3 c = lo + draw_vec3(u01, rng).cwiseProduct(hi - lo);
    const Vec3 start = c - 0.5 * travel * sweep, a = start - 0.5 * len * dir, b = start + 0.5 * len * dir;
    const double swept = swept_area_in_box(a, b, travel * sweep, lo, hi);
    if (swept < 1e-3) continue;
    CutOptions o;
    o.improve = false;
    o.snap = 0.02;
    const int steps = 2 + int(rng() % 7);
    const auto vol0 = label_volumes(m);
    Cutter cutter(m, o);
    cutter.start({a, b});
    for (int k = 1; k <= steps; ++k) cutter.advance({a + travel * sweep * (double(k) / steps), b + travel * sweep * (double(k) / steps)});
    cutter.finish();
    check_cut_invariants(m, vol0);
    const double opened = 0.5 * tagged_area(m, kTagCut);
    ++total;
    exact += std::abs(opened - swept) <= 0.01 * swept;
    INFO("cut " << i << ": swept " << swept << ", opened " << opened << ", " << steps << " steps");
    CHECK(opened == Approx(swept).epsilon(0.01));
  }
  WARN(exact << " of " << total << " random straight box cuts opened their swept area to 1%");
}

TEST_CASE("progressive: a blade swept across the Kuhn box's diagonal keeps the mesh valid and every volume (fuzz)",
          "[cut][progressive][fuzz]") {
  // Found by fuzz_cut: a blade placed outside the box, then a blade through
  // the main diagonal that every Kuhn tet shares, with snapping and improvement on.
  auto coordinate = [](int b) { return b < 128 ? -0.25 + 0.125 * (b % 13) : -0.3 + 1.6 * (b - 128) / 127.0; };
  auto point = [&](int x, int y, int z) { return Vec3(coordinate(x), coordinate(y), coordinate(z)); };
  TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
  m.discard_change();
  const auto vol0 = label_volumes(m);
  CutOptions opt;
  opt.snap = 0.02;
  opt.improve = true;
  opt.fragment_search_limit = 500;
  Cutter cutter(m, opt);
  double moved = 0;  // what the improvement's tolerance-mode contractions report moving
  cutter.start({point(0xbd, 0xff, 0xf8), point(0xfb, 0xfc, 0xff)});  // the harness's first advance() then
  check_cut_invariants(m, vol0, 1e-9, moved);
  moved += cutter.advance({point(0xfc, 0xfd, 0xfc), point(0, 0, 0)}).improve.volume_change;
  check_cut_invariants(m, vol0, 1e-9, moved);
}

TEST_CASE("progressive: finish()'s improvement in slices ends as well as in one call, and is the same every run",
          "[cut][progressive]") {
  // The liver, a blade from above its middle down 60% of its height in 12 steps, then withdrawn:
  // finish() embeds the front and starts its improvement; the rest comes in finish_more().
  const TetMesh liver = read_tet_mesh(std::string(INCISE_SOURCE_DIR) + "/samples/liver.msh");
  Vec3 lo = Vec3::Constant(1e300), hi = -lo;
  for (VertexId v : liver.vertices()) lo = lo.cwiseMin(liver.rest(v)), hi = hi.cwiseMax(liver.rest(v));
  const Vec3 c = 0.5 * (lo + hi), s = hi - lo;
  const Vec3 a(c.x(), lo.y() - 0.1 * s.y(), hi.z() + 0.05 * s.z()), b(c.x(), hi.y() + 0.1 * s.y(), hi.z() + 0.05 * s.z());
  auto cut = [&](int slice, int& calls, double& worst_ms) {
    TetMesh m = liver;
    const auto vol0 = label_volumes(m);
    CutOptions o;
    o.finish_improve_slice = slice;
    Cutter cutter(m, o);
    cutter.start({a, b});
    // What tolerance-mode contractions moved, the steps' included (the slices' checks below
    // once passed only because finish()'s own contractions reported more than the steps').
    double moved = 0;
    for (int k = 1; k <= 12; ++k) {
      const Vec3 off(0, 0, -0.65 * s.z() * k / 12);
      moved += cutter.advance({a + off, b + off}).improve.volume_change;
    }
    CutStepReport f = cutter.finish();
    moved += f.improve.volume_change;
    calls = 0;
    worst_ms = f.ms;
    CHECK(cutter.finishing() == (slice > 0));
    while (cutter.finishing()) {
      const CutStepReport r = cutter.finish_more();
      moved += r.improve.volume_change;
      worst_ms = std::max(worst_ms, r.ms);
      ++calls;
      REQUIRE(calls <= o.finish_improve_work / std::max(slice, 1) + 1);  // the operations are bounded
      // A slice that changes nothing would leave the next the same work: it ends the improvement.
      CHECK((!r.change.empty() || !cutter.finishing()));
      check_cut_invariants(m, vol0, 1e-9, moved);  // a valid mesh after every slice
    }
    CHECK(cutter.finish_more().change.empty());  // nothing left: an empty record
    return m;
  };
  int calls0 = 0, calls = 0, again_calls = 0;
  double ms0 = 0, ms = 0, again_ms = 0;
  const TetMesh whole = cut(0, calls0, ms0), sliced = cut(100, calls, ms), again = cut(100, again_calls, again_ms);
  CHECK(calls0 == 0);
  CHECK(calls > 0);
  auto quality = [](const TetMesh& m) {
    double worst = 180;
    std::size_t below = 0;
    for (TetId t : m.tets()) {
      const double d = tet_quality(m, t).min_dihedral;
      worst = std::min(worst, d);
      below += d < 10;
    }
    return std::pair(worst, below);
  };
  const auto [w0, b0] = quality(whole);
  const auto [w1, b1] = quality(sliced);
  INFO("one call: min " << w0 << " deg, " << b0 << " below 10; slices of 100: " << calls << " more calls, min " << w1
                        << " deg, " << b1 << " below 10; slowest call " << ms << " ms against " << ms0);
  // With finish()'s insertion (CutOptions::finish_insertion_below_deg) one call reached 6.2 deg
  // and 5 tets below 10, slices of 100 3.9 deg and 7 (before insertion: 3.7 deg and 15 both
  // ways): a slice holds at most 10 insertion attempts, and later slices seed only the tets
  // still short of the targets.
  CHECK(w1 >= 0.6 * w0);
  CHECK(b1 <= b0 + b0 / 4 + 2);
  // Operations, not time, bound each slice: the same cut twice is the same mesh.
  REQUIRE(again.num_tets() == sliced.num_tets());
  for (TetId t : sliced.tets()) REQUIRE(again.tet_vertices(t) == sliced.tet_vertices(t));
  // A new cut drops what is left of the last one's improvement.
  TetMesh m = liver;
  CutOptions o;
  o.finish_improve_slice = 10;
  Cutter cutter(m, o);
  cutter.start({a, b});
  cutter.advance({a + Vec3(0, 0, -0.5 * s.z()), b + Vec3(0, 0, -0.5 * s.z())});
  cutter.finish();
  REQUIRE(cutter.finishing());
  cutter.start({a, b});
  CHECK_FALSE(cutter.finishing());
}

TEST_CASE("progressive: exact_volumes keeps every label's volume to rounding through random cuts",
          "[cut][progressive]") {
  // The sample liver (labels 85, 127, 255), four random straight cuts swept down in 10 steps
  // each: with exact_volumes (the default) the improvement may not move the surface or a label
  // interface; without it its tolerance contractions move them by a hair (docs/cut.md#label-volumes).
  const TetMesh liver = read_tet_mesh(std::string(INCISE_SOURCE_DIR) + "/samples/liver.msh");
  Vec3 lo = Vec3::Constant(1e300), hi = -lo;
  for (VertexId v : liver.vertices()) lo = lo.cwiseMin(liver.rest(v)), hi = hi.cwiseMax(liver.rest(v));
  const Vec3 ext = hi - lo;
  auto worst_change = [&](bool exact, unsigned seed) {
    TetMesh m = liver;
    const auto before = label_volumes(m);
    double body = 0;
    for (const auto& [l, v] : before) body += v;
    CutOptions o;
    o.exact_volumes = exact;
    Cutter cutter(m, o);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.3, 0.7), turn(0, 3.14159265358979323846), depth(0.4, 0.9);
    for (int k = 0; k < 4; ++k) {
      const Vec3 c = lo + Vec3(u(rng) * ext.x(), u(rng) * ext.y(), 1.05 * ext.z());
      const double a = turn(rng);
      const Vec3 dir(std::cos(a), std::sin(a), 0), d(0, 0, -depth(rng) * ext.z() / 10);
      const Vec3 p = c - 0.8 * ext.maxCoeff() * dir, q = c + 0.8 * ext.maxCoeff() * dir;
      cutter.start({p, q});
      for (int s = 1; s <= 10; ++s) cutter.advance({p + s * d, q + s * d});
      cutter.finish();
    }
    REQUIRE_NOTHROW(m.validate({true, true}));
    double worst = 0;
    const auto after = label_volumes(m);
    for (const auto& [l, v] : before) worst = std::max(worst, std::abs(after.at(l) - v));
    return worst / body;
  };
  for (unsigned seed : {1u, 2u}) {
    const double plain = worst_change(false, seed), exact = worst_change(true, seed);
    INFO("seed " << seed << ": largest label volume change / body: not exact " << plain << ", exact " << exact);
    CHECK(exact < 1e-12);
    CHECK(plain > 1e-9);  // what exact_volumes is for
  }
}

TEST_CASE("progressive: the cut is open up to the blade at every step (provisional pieces)", "[cut][progressive]") {
  // The partial cut above in 40 steps of 0.015: the blade edge goes from 0.1 above the top to
  // 0.5 deep. The area open after a step, against the area the blade has swept inside the box.
  const Vec3 a(2.03, -0.5, 1.1), b(2.03, 1.5, 1.1), d(0, 0, -0.015);
  double worst[2] = {1e9, 1e9};
  std::size_t tets[2] = {0, 0};
  for (bool provisional : {false, true}) {
    TetMesh m = box4();
    const auto vol0 = label_volumes(m);
    CutOptions o;
    o.provisional = provisional;
    Cutter cutter(m, o);
    cutter.start({a, b});
    double moved = 0;
    for (int k = 1; k <= 40; ++k) {
      const CutStepReport r = cutter.advance({a + k * d, b + k * d});
      moved += r.improve.volume_change;
      check_cut_invariants(m, vol0, 1e-9, moved);
      const double depth = std::max(0.0, 1.0 - (a.z() + k * d.z()));
      const double open = 0.5 * tagged_area(m, kTagCut);
      INFO("provisional " << provisional << ", step " << k << ", depth " << depth << ": open " << open);
      CHECK(open <= depth + 1e-9);  // never past the blade
      if (depth >= 0.25) worst[provisional] = std::min(worst[provisional], open / depth);
      if (provisional && depth >= 0.25) CHECK(r.provisional_faces > 0);
    }
    moved += cutter.finish().improve.volume_change;
    check_cut_invariants(m, vol0, 1e-9, moved);
    CHECK(0.5 * tagged_area(m, kTagCut) == Approx(0.5).epsilon(0.01));
    CHECK(vertex_parts(m) == 1);
    tets[provisional] = m.num_tets();
  }
  INFO("worst share open: " << worst[0] << " committed only, " << worst[1] << " with provisional pieces");
  CHECK(worst[0] < 0.9);   // the tets the blade is in wait: the opening trails by them
  CHECK(worst[1] >= 0.9);  // the bound
  // The provisional pieces are taken back: the committed cut is the same up to the order of ids.
  CHECK(std::abs(double(tets[1]) - double(tets[0])) <= 0.02 * double(tets[0]));
}
