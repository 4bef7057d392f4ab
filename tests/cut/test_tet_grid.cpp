// The first-contact grid: exact (a superset of the brute-force answer) through edits it is
// told about and edits it is not, local (a query near the blade lists few tets), and right on
// a deformed mesh whatever the displacement.
#include <catch2/catch.hpp>

#include <random>
#include <unordered_set>

#include "cut/cutter.h"
#include "cut/tet_grid.h"
#include "mesh/generate.h"
#include "quality/components.h"
#include "quality/improve.h"
#include "testing/mesh_edits.h"
#include "testing/draws.h"

using namespace incise;
using namespace incise::testing;

namespace {
// Tets whose rest box meets [lo, hi], by brute force.
std::unordered_set<std::uint32_t> brute(const TetMesh& m, const Vec3& lo, const Vec3& hi) {
  std::unordered_set<std::uint32_t> out;
  for (TetId t : m.tets()) {
    Vec3 a = m.rest(m.tet_vertices(t)[0]), b = a;
    for (VertexId v : m.tet_vertices(t)) {
      a = a.cwiseMin(m.rest(v));
      b = b.cwiseMax(m.rest(v));
    }
    if ((a.array() <= hi.array()).all() && (b.array() >= lo.array()).all()) out.insert(t.idx());
  }
  return out;
}

void check_queries(TetGrid& g, const TetMesh& m, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-0.1, 1.1), s(0.0, 0.3);
  for (int q = 0; q < 20; ++q) {
    const Vec3 c = draw_vec3(u, rng);
    const Vec3 h = draw_vec3(s, rng);
    const auto want = brute(m, c - h, c + h);
    const auto got = g.query(m, c - h, c + h, 0.0);
    std::unordered_set<std::uint32_t> seen;
    for (TetId t : got) {
      REQUIRE(m.is_alive(t));
      REQUIRE(seen.insert(t.idx()).second);  // each listed once
    }
    CHECK(seen == want);  // the grid's boxes are exact: neither more nor fewer
  }
}
}  // namespace

TEST_CASE("the first-contact grid answers like a scan through edits", "[cut][grid]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {6, 6, 6});
  m.discard_change();
  TetGrid g;
  g.build(m);
  std::mt19937 rng(5);
  check_queries(g, m, rng);
  for (int round = 0; round < 20; ++round) {
    for (int e = 0; e < 30; ++e) random_edit(m, rng, /*allow_remove=*/true);
    g.update(m, m.take_change());
    check_queries(g, m, rng);
  }
  // Smoothing moves rest positions (tets re-added under the same ids).
  ImproveOptions io;
  io.time_budget_ms = 0;
  improve(m, io);
  g.update(m, m.take_change());
  check_queries(g, m, rng);
}

TEST_CASE("first contact lists tets near the blade only", "[cut][grid]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {30, 30, 30});  // 162k tets
  m.discard_change();
  TetGrid g;
  g.build(m);
  const auto near = g.query(m, Vec3(0.4, 0.4, 0.95), Vec3(0.6, 0.6, 1.2), 0.0);
  CHECK(!near.empty());
  CHECK(near.size() < m.num_tets() / 100);
  // A blade far from the body meets nothing and lists nothing.
  CHECK(g.query(m, Vec3(3, 3, 3), Vec3(4, 4, 4), 0.0).empty());
}

TEST_CASE("first contact on a deformed mesh, bound given or measured", "[cut][grid]") {
  for (int given = 0; given < 2; ++given) {
    TetMesh m = make_box(Vec3(1, 1, 1), {5, 5, 5});
    m.discard_change();
    // The body moved far away (three sizes along x) and sheared: no rest box is near the blade.
    std::vector<Vec3> cur(m.vertex_capacity());
    double bound = 0;
    for (VertexId v : m.vertices()) {
      cur[v.idx()] = m.rest(v) + Vec3(3.0 + 0.2 * m.rest(v).z(), 0, 0);
      bound = std::max(bound, (cur[v.idx()] - m.rest(v)).norm());
    }
    auto pos = [&](VertexId v) { return cur[v.idx()]; };
    CutOptions o;
    o.improve = false;
    Cutter cutter(m, o);
    const double y = 0.47;
    cutter.start({Vec3(2.5, y, 1.5), Vec3(4.6, y, 1.5)});
    double disp = given ? bound : Cutter::kUnknownDisplacement;
    for (int s = 1; s <= 10; ++s) {
      const double z = 1.5 - 0.2 * s;
      const CutStepReport r = cutter.advance({Vec3(2.5, y, z), Vec3(4.6, y, z)}, pos, disp);
      cur.resize(m.vertex_capacity());
      for (const VertexOrigin& ov : r.change.added_vertices) {
        Vec3 x = Vec3::Zero();
        for (int k = 0; k < 4; ++k)
          if (ov.parents[k].is_valid()) x += ov.weights[k] * cur[ov.parents[k].idx()];
        cur[ov.vertex.idx()] = x;
      }
    }
    m.validate({true, true});
    CHECK(tet_components(m).count == 2);
  }
}

TEST_CASE("edits the cutter was not told about rebuild the grid", "[cut][grid]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
  m.discard_change();
  CutOptions o;
  o.improve = false;
  Cutter cutter(m, o);
  // Split every tet in a slab elsewhere: the new tets are not in the cutter's grid.
  std::mt19937 rng(2);
  for (int e = 0; e < 200; ++e) random_edit(m, rng);
  m.take_change();
  const auto r = cutter.cut_plane(Vec3(0.5, 0.5, 0.37), Vec3(0.1, 0.2, 1.0));
  CHECK(r.cut_faces > 0);
  m.validate({true, true});
  CHECK(tet_components(m).count == 2);
}
