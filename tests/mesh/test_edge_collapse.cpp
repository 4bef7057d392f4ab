// Edge contraction: a split undone by a collapse gives back a valid mesh with the same volume,
// tags and tet count; the refusals (link condition, boundary, orientation, labels); the
// TopologyChange names what changed; random collapses keep every invariant.
#include <catch2/catch.hpp>

#include <map>
#include <random>

#include "mesh/edge_collapse.h"
#include "mesh/generate.h"
#include "testing/mesh_edits.h"
#include "testing/mesh_measures.h"

using namespace incise;
using incise::testing::vertex_at;
using incise::testing::label_volumes;
using incise::testing::tag_areas;

namespace {


void check_same(const std::map<int, double>& a, const std::map<int, double>& b) {
  REQUIRE(a.size() == b.size());
  for (const auto& [k, v] : a) CHECK(std::abs(b.at(k) - v) <= 1e-12 * (1 + std::abs(v)));
}
void check_same(const std::map<std::uint16_t, double>& a, const std::map<std::uint16_t, double>& b) {
  REQUIRE(a.size() == b.size());
  for (const auto& [k, v] : a) CHECK(std::abs(b.at(k) - v) <= 1e-12 * (1 + std::abs(v)));
}

}  // namespace

TEST_CASE("collapsing a split edge gives back a valid mesh with the same volume and tags", "[mesh][collapse]") {
  struct Case {
    const char* name;
    Vec3 a, b;  // the edge split (on the 2x2x2 box of unit cells)
  };
  // Interior edge, an edge inside the flat bottom face (the new vertex is on the boundary), and
  // an edge on the box's edge (the new vertex is on a straight crease).
  for (const Case& c : {Case{"interior", Vec3(1, 1, 1), Vec3(1, 0, 1)}, Case{"boundary", Vec3(1, 1, 0), Vec3(1, 0, 0)},
                        Case{"crease", Vec3(0, 0, 0), Vec3(1, 0, 0)}})
    for (double s : {0.5, 0.01, 0.99}) {
      INFO(c.name << " s=" << s);
      TetMesh m = make_box(Vec3(2, 2, 2), {2, 2, 2});
      for (TetId t : m.tets()) {  // a second label in the far corner cube, away from the edges
        Vec3 ctr = Vec3::Zero();
        for (VertexId v : m.tet_vertices(t)) ctr += m.rest(v) / 4;
        if (ctr.minCoeff() > 1) m.set_label(t, 3);
      }
      m.discard_change();
      const std::size_t tets0 = m.num_tets(), verts0 = m.num_vertices();
      const auto vol0 = label_volumes(m);
      const auto area0 = tag_areas(m);
      const VertexId a = vertex_at(m, c.a), b = vertex_at(m, c.b);
      const VertexId x = m.split_edge(a, b, s);
      (void)m.take_change();
      const VertexId keep = s < 0.5 ? a : b;  // the short edge
      const std::size_t star = m.incident_tets(x).size(), around = m.edge_star(keep, x).tets.size();
      const CollapseCheck chk = check_collapse(m, keep, x);
      INFO(to_string(chk.refusal));
      REQUIRE(chk.ok());
      collapse_edge(m, chk.plan);
      REQUIRE_NOTHROW(m.validate({true, true}));
      CHECK(m.num_tets() == tets0);
      CHECK(m.num_vertices() == verts0);
      CHECK(!m.is_alive(x));
      check_same(vol0, label_volumes(m));
      check_same(area0, tag_areas(m));
      // The record: the edge's tets removed, the rest of x's star removed + added, x removed.
      const TopologyChange ch = m.take_change();
      CHECK(ch.removed_tets.size() == star);
      CHECK(ch.added_tets.size() == star - around);
      REQUIRE(ch.removed_vertices.size() == 1);
      CHECK(ch.removed_vertices[0] == x);
      CHECK(ch.added_vertices.empty());
      for (VertexId v : ch.touched_vertices) CHECK(m.is_alive(v));
    }
}

TEST_CASE("a vertex split and collapsed in one batch is listed as added, then removed", "[mesh][collapse]") {
  TetMesh m = make_box(Vec3(2, 2, 2), {2, 2, 2});
  m.discard_change();
  const VertexId a = vertex_at(m, Vec3(1, 1, 1)), b = vertex_at(m, Vec3(2, 2, 2));
  const VertexId x = m.split_edge(a, b, 0.1);
  REQUIRE(collapse_edge(m, a, x));
  const TopologyChange ch = m.take_change();
  // Later records of a batch may name x as a parent, so its record stays; consumers apply
  // removals last.
  REQUIRE(ch.added_vertices.size() == 1);
  CHECK(ch.added_vertices[0].vertex == x);
  REQUIRE(ch.removed_vertices.size() == 1);
  CHECK(ch.removed_vertices[0] == x);
  for (TetId t : ch.added_tets) CHECK(m.is_alive(t));
  m.validate({true, true});
  // Its id is free again only after the batch: the next vertex reuses it.
  CHECK(m.split_edge(a, b, 0.5) == x);
}

TEST_CASE("collapses that would change the mesh are refused and leave it intact", "[mesh][collapse]") {
  TetMesh m = make_box(Vec3(2, 2, 2), {2, 2, 2});
  m.discard_change();
  auto at = [&](double x, double y, double z) { return vertex_at(m, Vec3(x, y, z)); };
  // Link condition: both ends on the boundary, the edge (a cube's main diagonal) inside.
  {
    TetMesh cube = make_box(Vec3(1, 1, 1), {1, 1, 1});
    CHECK(check_collapse(cube, vertex_at(cube, Vec3(0, 0, 0)), vertex_at(cube, Vec3(1, 1, 1))).refusal ==
          CollapseRefusal::Link);
  }
  // A boundary vertex may not leave the boundary for an interior one.
  CHECK(check_collapse(m, at(1, 1, 1), at(1, 1, 0)).refusal == CollapseRefusal::Boundary);
  // A corner stays; a crease vertex may go only along its crease.
  CHECK(check_collapse(m, at(1, 0, 0), at(0, 0, 0)).refusal == CollapseRefusal::Boundary);
  CHECK(check_collapse(m, at(1, 1, 0), at(1, 0, 0)).refusal == CollapseRefusal::Boundary);
  CHECK(check_collapse(m, at(1, 0, 1), at(1, 0, 0)).refusal == CollapseRefusal::Boundary);
  CHECK(check_collapse(m, at(0, 0, 0), at(1, 0, 0)).ok());
  // The centre onto a corner or onto the bottom face's middle: its star is star-shaped from both.
  CHECK(check_collapse(m, at(0, 0, 0), at(1, 1, 1)).ok());
  CHECK(check_collapse(m, at(1, 1, 0), at(1, 1, 1)).ok());
  // Not an edge / the same vertex / a dead vertex.
  CHECK(check_collapse(m, at(0, 0, 0), at(2, 2, 2)).refusal == CollapseRefusal::NotAnEdge);
  CHECK(check_collapse(m, at(0, 0, 0), at(0, 0, 0)).refusal == CollapseRefusal::NotAnEdge);
  // A tag border on a flat face is a crease: a vertex on a straight stretch of it may go along
  // it (the tag regions keep their shape), not across it, and the border's corner stays.
  {
    TetMesh t = make_box(Vec3(2, 2, 2), {2, 2, 2});
    const VertexId p = vertex_at(t, Vec3(1, 1, 0)), q = vertex_at(t, Vec3(1, 0, 0));
    const VertexId x = t.split_edge(p, q, 0.2);
    for (const auto& f : t.boundary_faces()) {
      Vec3 c = Vec3::Zero();
      for (VertexId v : f.vertices) c += t.rest(v) / 3;
      if (c.z() < 1e-12 && c.x() < 1 && c.y() < 1) t.set_face_tag(f.tet, f.local, 20);  // a quadrant
    }
    t.discard_change();
    CHECK(check_collapse(t, vertex_at(t, Vec3(0, 1, 0)), p).refusal == CollapseRefusal::Boundary);  // corner
    CHECK(check_collapse(t, vertex_at(t, Vec3(2, 1, 0)), p).refusal == CollapseRefusal::Boundary);
    const auto area0 = tag_areas(t);
    REQUIRE(collapse_edge(t, q, x));  // along the border
    t.validate({true, true});
    check_same(area0, tag_areas(t));
  }
  // A vertex on an interface between labels stays.
  {
    TetMesh t = make_box(Vec3(2, 2, 2), {2, 2, 2});
    for (TetId u : t.tets()) {
      Vec3 c = Vec3::Zero();
      for (VertexId v : t.tet_vertices(u)) c += t.rest(v) / 4;
      if (c.z() < 1) t.set_label(u, 2);
    }
    const VertexId x = t.split_edge(vertex_at(t, Vec3(1, 1, 1)), vertex_at(t, Vec3(1, 0, 1)), 0.1);
    CHECK(check_collapse(t, vertex_at(t, Vec3(1, 1, 1)), x).refusal == CollapseRefusal::Labels);
  }
  REQUIRE_FALSE(m.has_pending_change());
  m.validate({true, true});
}

TEST_CASE("random collapses keep every invariant, each label's volume and the tagged areas", "[mesh][collapse]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {5, 5, 5});
  testing::jitter(m, 0.25, 4);
  for (TetId t : m.tets())
    if (m.rest(m.tet_vertices(t)[0]).x() < 0.4) m.set_label(t, 2);
  m.discard_change();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0.02, 0.98);
  int done = 0, refused = 0;
  std::map<CollapseRefusal, int> why;
  for (int i = 0; i < 600; ++i) {
    // Split a random edge, then collapse some random edge of the new vertex's star, either way.
    const TetId t = testing::random_tet(m, rng);
    const auto tv = m.tet_vertices(t);
    const VertexId x = m.split_edge(tv[rng() % 2], tv[2 + rng() % 2], u(rng));
    (void)m.take_change();
    const auto vol0 = label_volumes(m);
    const auto area0 = tag_areas(m);
    const auto star = m.incident_tets(x);
    const TetId s = star[rng() % star.size()];
    VertexId y = m.tet_vertices(s)[rng() % 4];
    if (y == x) y = m.tet_vertices(s)[(m.local_index(s, x) + 1) % 4];
    const bool flip = rng() % 2;
    const VertexId keep = flip ? y : x, remove = flip ? x : y;
    const std::size_t tets = m.num_tets();
    const CollapseCheck chk = check_collapse(m, keep, remove);
    if (!chk.ok()) {
      ++refused;
      ++why[chk.refusal];
      CHECK(m.num_tets() == tets);
      CHECK_FALSE(m.has_pending_change());
      continue;
    }
    collapse_edge(m, chk.plan);
    ++done;
    REQUIRE_NOTHROW(m.validate({true, true}));
    check_same(vol0, label_volumes(m));
    check_same(area0, tag_areas(m));
    const TopologyChange ch = m.take_change();
    REQUIRE(ch.removed_vertices.size() == 1);
    CHECK(ch.removed_vertices[0] == remove);
    for (TetId a : ch.added_tets) CHECK(m.is_alive(a));
    for (TetId r : ch.removed_tets) CHECK((!m.is_alive(r) || std::count(ch.added_tets.begin(), ch.added_tets.end(), r) == 1));
  }
  INFO(done << " collapsed, " << refused << " refused");
  for (auto [r, n] : why) UNSCOPED_INFO(to_string(r) << ": " << n);
  CHECK(done > 100);
  // Every kind of refusal a jittered two-label box can produce happened (so each check is
  // exercised, and the collapses it let through all gave valid meshes above).
  for (CollapseRefusal r : {CollapseRefusal::Link, CollapseRefusal::Orientation, CollapseRefusal::Boundary,
                            CollapseRefusal::Labels})
    CHECK(why[r] > 0);
}
