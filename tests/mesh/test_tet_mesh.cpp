// Mesh core: invariants after every edit, volume and tags preserved, batch records, locality.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <set>
#include <random>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "mesh/tet_mesh.h"
#include "testing/mesh_edits.h"

using namespace incise;
using namespace incise::testing;

namespace {

double face_tag_area(const TetMesh& m, std::uint16_t tag) {
  double a = 0;
  for (const auto& f : m.boundary_faces())
    if (f.tag == tag)
      a += 0.5 * (m.rest(f.vertices[1]) - m.rest(f.vertices[0])).cross(m.rest(f.vertices[2]) - m.rest(f.vertices[0])).norm();
  return a;
}

}  // namespace

TEST_CASE("generated meshes are valid, closed and have the analytic volume", "[mesh]") {
  TetMesh box = make_box(Vec3(2, 3, 4), {3, 4, 5});
  box.validate({true, true});
  CHECK(box.num_tets() == 6 * 3 * 4 * 5);
  CHECK(box.num_vertices() == 4 * 5 * 6);
  CHECK(box.total_volume() == Approx(24.0).epsilon(1e-12));
  CHECK(face_tag_area(box, kTagSurface) == Approx(2 * (6 + 8 + 12)).epsilon(1e-12));
  // The mirrored split (diagonals alternate) conforms too: no face left open inside, so the
  // tagged boundary is the box's surface alone.
  TetMesh mirrored = make_box(Vec3(2, 3, 4), {3, 4, 5}, 1, BoxSplit::Mirrored);
  mirrored.validate({true, true});
  CHECK(mirrored.num_tets() == 6 * 3 * 4 * 5);
  CHECK(mirrored.boundary_faces().size() == box.boundary_faces().size());
  CHECK(mirrored.total_volume() == Approx(24.0).epsilon(1e-12));
  CHECK(face_tag_area(mirrored, kTagSurface) == Approx(2 * (6 + 8 + 12)).epsilon(1e-12));

  for (int n : {1, 2, 5, 10}) {
    TetMesh ball = make_ellipsoid(Vec3(1, 1, 1), n);
    ball.validate({true, true});
    // The polyhedral ball converges to 4/3 pi from below.
    CHECK(ball.total_volume() < 4.0 / 3.0 * M_PI);
  }
  TetMesh fine = make_ellipsoid(Vec3(3, 2, 1), 12);
  fine.validate({true, true});
  CHECK(fine.total_volume() == Approx(4.0 / 3.0 * M_PI * 6).epsilon(0.03));
}

TEST_CASE("bad generator arguments are refused", "[mesh]") {
  CHECK_THROWS_AS(make_box(Vec3(0, 1, 1), {1, 1, 1}), InvalidArgument);
  CHECK_THROWS_AS(make_box(Vec3(1, 1, 1), {0, 1, 1}), InvalidArgument);
  CHECK_THROWS_AS(make_ellipsoid(Vec3(1, NAN, 1), 2), InvalidArgument);
}

TEST_CASE("thousands of random edits keep every invariant, the volume and the tagged area", "[mesh]") {
  std::vector<TetMesh> meshes;
  meshes.push_back(make_box(Vec3(1, 1, 1), {3, 3, 3}));
  meshes.push_back(make_ellipsoid(Vec3(2, 1, 0.5), 2));
  meshes.push_back(make_box(Vec3(1e-6, 2e-6, 1e-6), {2, 3, 2}));  // tiny scale
  meshes.push_back(make_box(Vec3(1e6, 1e6, 3e6), {2, 2, 4}));     // huge scale
  meshes.push_back(make_box(Vec3(1, 1, 1), {4, 4, 4}));
  jitter(meshes.back(), 0.2, 11);
  meshes.push_back(make_ellipsoid(Vec3(1, 1, 1), 3));
  jitter(meshes.back(), 0.2, 12);
  std::uint32_t seed = 1;
  for (TetMesh& m : meshes) {
    std::mt19937 rng(seed++);
    const double vol = m.total_volume();
    const double area = face_tag_area(m, kTagSurface);
    int edits = 0;
    for (int i = 0; i < 1500; ++i) {
      if (!random_edit(m, rng)) continue;
      ++edits;
      m.validate();
      if (m.num_tets() > 4000) break;
    }
    INFO("mesh " << seed - 1 << " after " << edits << " edits");
    m.validate({true, true});
    CHECK(edits > 300);
    CHECK(m.total_volume() == Approx(vol).epsilon(1e-9));
    CHECK(face_tag_area(m, kTagSurface) == Approx(area).epsilon(1e-9));
  }
}

TEST_CASE("cavity insertions keep every invariant, the volume, the labels and the tags", "[mesh][cavity]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
  jitter(m, 0.2, 21);
  for (TetId t : m.tets())
    if (t.idx() % 4 == 0) m.set_label(t, 3);
  auto label_volume = [&](int lab) {
    double v = 0;
    for (TetId t : m.tets())
      if (m.label(t) == lab) v += m.volume(t);
    return v;
  };
  const double vol0 = label_volume(0), vol3 = label_volume(3), area = face_tag_area(m, kTagSurface);
  std::mt19937 rng(4);
  int done = 0, multi = 0;
  m.discard_change();
  for (int i = 0; i < 400; ++i) {
    const std::size_t before = m.num_tets();
    if (!random_cavity_insertion(m, rng)) continue;
    ++done;
    multi += m.num_tets() > before + 3;  // more than a 1-4 split: a cavity of several tets
    m.validate();
  }
  m.validate({true, true});
  CHECK(done > 100);
  CHECK(multi > 20);
  CHECK(label_volume(0) == Approx(vol0).epsilon(1e-12));
  CHECK(label_volume(3) == Approx(vol3).epsilon(1e-12));
  CHECK(face_tag_area(m, kTagSurface) == Approx(area).epsilon(1e-12));
  const TopologyChange ch = m.take_change();
  CHECK(ch.added_vertices.size() == static_cast<std::size_t>(done));
  // Each new vertex sits where its record's parents put it.
  for (const VertexOrigin& o : ch.added_vertices) {
    Vec3 p = Vec3::Zero();
    for (int k = 0; k < 4; ++k)
      if (o.parents[k].is_valid()) p += o.weights[k] * m.rest(o.parents[k]);
    CHECK((p - m.rest(o.vertex)).norm() < 1e-12);
  }
}

TEST_CASE("boundary cavity insertions split a boundary face or edge in place, keeping its tag", "[mesh][cavity]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
  jitter(m, 0.2, 22);
  for (TetId t : m.tets())  // a second tag on part of the surface
    for (int f = 0; f < 4; ++f)
      if (!m.neighbor(t, f).is_valid() && t.idx() % 3 == 0) m.set_face_tag(t, f, kTagCut);
  const double vol = m.total_volume(), surface = face_tag_area(m, kTagSurface), cut = face_tag_area(m, kTagCut);
  const std::size_t faces = m.boundary_faces().size();
  std::mt19937 rng(9);
  int on_face = 0, on_edge = 0;
  m.discard_change();
  for (int i = 0; i < 2000; ++i) {
    const TetId t = random_tet(m, rng);
    const int f = static_cast<int>(rng() % 4);
    if (m.neighbor(t, f).is_valid()) continue;
    const auto fv = m.face_vertices(t, f);
    // The cavity: t and its neighbours (those around the edge too, for an edge insertion).
    std::vector<TetId> cavity = {t};
    for (int g = 0; g < 4; ++g)
      if (m.neighbor(t, g).is_valid() && rng() % 2) cavity.push_back(m.neighbor(t, g));
    const bool edge = rng() % 2;
    const double a = 0.3 + 0.4 * double(rng() % 100) / 100;
    bool ok;
    if (edge) {
      const VertexId par[2] = {fv[0], fv[1]};
      const double w[2] = {a, 1 - a};
      for (TetId u : m.incident_tets(fv[0]))
        if (m.local_index(u, fv[1]) >= 0 && std::find(cavity.begin(), cavity.end(), u) == cavity.end())
          cavity.push_back(u);
      ok = m.is_boundary_cavity_insertion_ok(cavity, par, w);
      if (ok) m.insert_in_cavity_on_boundary(cavity, par, w);
      on_edge += ok;
    } else {
      const double w[3] = {a / 2, a / 2, 1 - a};
      ok = m.is_boundary_cavity_insertion_ok(cavity, fv, w);
      if (ok) m.insert_in_cavity_on_boundary(cavity, fv, w);
      on_face += ok;
    }
    if (ok) m.validate();
  }
  m.validate({true, true});
  CHECK(on_face > 30);
  CHECK(on_edge > 30);
  CHECK(m.total_volume() == Approx(vol).epsilon(1e-12));
  CHECK(face_tag_area(m, kTagSurface) == Approx(surface).epsilon(1e-12));
  CHECK(face_tag_area(m, kTagCut) == Approx(cut).epsilon(1e-12));
  CHECK(m.boundary_faces().size() == faces + 2 * std::size_t(on_face + on_edge));
  // A face point must lie inside its face; an interior face is not a boundary face.
  const TetId t = m.tets().front();
  const double bad[3] = {0.5, 0.6, -0.1};
  CHECK_FALSE(m.is_boundary_cavity_insertion_ok(std::vector<TetId>{t}, m.face_vertices(t, 0), bad));
}

TEST_CASE("cavity insertions that would orphan a vertex, mix labels or invert are refused", "[mesh][cavity]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {3, 3, 3});
  jitter(m, 0.2, 5);
  VertexId inner;
  for (VertexId v : m.vertices())
    if ((m.rest(v) - Vec3(1, 1, 1) / 3).norm() < 0.2) inner = v;
  REQUIRE(inner.is_valid());
  const auto star = m.incident_tets(inner);
  const std::vector<TetId> cavity(star.begin(), star.end());
  // The whole star of an interior vertex: the vertex would be left without tets.
  CHECK_FALSE(m.is_cavity_insertion_ok(cavity, m.rest(inner) + Vec3(1e-3, 0, 0)));
  // One tet: a point outside it does not see all its faces.
  const TetId t = cavity.front();
  Vec3 c = Vec3::Zero();
  for (VertexId v : m.tet_vertices(t)) c += m.rest(v) / 4;
  CHECK(m.is_cavity_insertion_ok(std::vector<TetId>{t}, c));
  CHECK_FALSE(m.is_cavity_insertion_ok(std::vector<TetId>{t}, c + Vec3(5, 0, 0)));
  // Two labels in one cavity.
  const TetId n = m.neighbor(t, 0);
  m.set_label(n, 7);
  CHECK_FALSE(m.is_cavity_insertion_ok(std::vector<TetId>{t, n}, c));
  const std::size_t tets = m.num_tets();
  const VertexId parents[1] = {inner};
  const double w[1] = {1.0};
  CHECK_THROWS_AS(m.insert_in_cavity(cavity, parents, w), InvalidArgument);
  CHECK(m.num_tets() == tets);
  m.validate();
}

TEST_CASE("flip 2-3 and 3-2 are inverse, 4-4 keeps volume and boundary", "[mesh]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {3, 3, 3});
  jitter(m, 0.25, 5);
  int flipped = 0;
  for (TetId t : m.tets()) {
    for (int f = 0; f < 4; ++f) {
      if (!m.is_alive(t) || !m.is_flip23_ok(t, f)) continue;
      VertexId a = m.tet_vertices(t)[f];
      TetId u = m.neighbor(t, f);
      VertexId b;
      for (VertexId x : m.tet_vertices(u))
        if (m.local_index(t, x) < 0) b = x;
      const std::size_t n = m.num_tets();
      auto three = m.flip23(t, f);
      m.validate();
      CHECK(m.num_tets() == n + 1);
      for (TetId x : three) CHECK(m.local_index(x, a) >= 0);
      REQUIRE(m.is_flip32_ok(a, b));
      m.flip32(a, b);
      m.validate();
      CHECK(m.num_tets() == n);
      ++flipped;
    }
  }
  CHECK(flipped > 10);

  // Edges of a Kuhn box interior with exactly four tets around them admit a 4-4 flip.
  TetMesh k = make_box(Vec3(1, 1, 1), {2, 2, 2});
  int flips44 = 0;
  for (VertexId a : k.vertices())
    for (VertexId b : k.vertices()) {
      if (!(a < b)) continue;
      for (int d = 0; d < 2; ++d)
        if (k.is_flip44_ok(a, b, d)) {
          const double vol = k.total_volume();
          k.flip44(a, b, d);
          k.validate({true, true});
          CHECK(k.total_volume() == Approx(vol).epsilon(1e-12));
          ++flips44;
          break;
        }
    }
  CHECK(flips44 > 0);
}

TEST_CASE("a batch yields one normalized TopologyChange", "[mesh]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {1, 1, 1});
  CHECK(!m.has_pending_change());
  TetId t0 = m.tets().front();
  auto v = m.tet_vertices(t0);
  VertexId p = m.split_edge(v[0], v[1], 0.25);
  TopologyChange ch = m.take_change();
  REQUIRE(ch.added_vertices.size() == 1);
  CHECK(ch.added_vertices[0].vertex == p);
  CHECK(ch.added_vertices[0].parents[0] == v[0]);
  CHECK(ch.added_vertices[0].weights[0] == 0.75);
  CHECK(ch.added_vertices[0].weights[1] == 0.25);
  CHECK((m.rest(p) - (0.75 * m.rest(v[0]) + 0.25 * m.rest(v[1]))).norm() < 1e-15);
  const auto star = m.edge_star(v[0], p);
  CHECK(ch.removed_tets.size() == star.tets.size());
  CHECK(ch.added_tets.size() == 2 * star.tets.size());
  for (TetId t : ch.added_tets) CHECK(m.is_alive(t));
  CHECK(std::find(ch.touched_vertices.begin(), ch.touched_vertices.end(), p) != ch.touched_vertices.end());
  CHECK(!m.has_pending_change());

  // A tet added and removed in the same batch appears in neither list.
  TetMesh s = make_box(Vec3(1, 1, 1), {1, 1, 1});
  VertexId q = s.split_tet(s.tets().front());
  TopologyChange c2 = s.take_change();
  CHECK(c2.removed_tets.size() == 1);
  CHECK(c2.added_tets.size() == 4);
  // The parent id is recycled by a child: it is listed as removed and as added.
  CHECK(std::find(c2.added_tets.begin(), c2.added_tets.end(), c2.removed_tets[0]) != c2.added_tets.end());
  VertexId other = s.tet_vertices(c2.added_tets[0])[0] == q ? s.tet_vertices(c2.added_tets[0])[1]
                                                                 : s.tet_vertices(c2.added_tets[0])[0];
  for (TetId t : s.edge_star(q, other).tets) s.split_tet(t);
  for (TetId t : s.take_change().added_tets) CHECK(s.is_alive(t));
}

TEST_CASE("invalid edits are refused and leave the mesh intact", "[mesh]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {1, 1, 1});
  auto t = m.tets().front();
  auto v = m.tet_vertices(t);
  // The same tet again would put three tets on each of its faces.
  CHECK_THROWS_AS(m.add_tet(v[0], v[1], v[2], v[3]), InvalidMesh);
  CHECK_THROWS_AS(m.add_tet(v[0], v[0], v[2], v[3]), InvalidMesh);
  CHECK_THROWS_AS(m.remove_vertex(v[0]), InvalidMesh);
  CHECK_THROWS_AS(m.split_edge(v[0], v[1], 1.0), InvalidArgument);
  CHECK_THROWS_AS(m.flip23(t, 0), InvalidArgument);  // box corner tets: boundary or non-convex
  m.validate();
  CHECK(m.num_tets() == 6);
}

TEST_CASE("validate() names the broken invariant", "[mesh]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {1, 1, 1});
  VertexId v = m.tet_vertices(m.tets().front())[0];
  m.set_rest(v, Vec3(5, 5, 5));  // folds tets over
  try {
    m.validate();
    FAIL("validate accepted an inverted tet");
  } catch (const InvalidMesh& e) {
    CHECK(std::string(e.what()).find("not positively oriented") != std::string::npos);
  }
  // Two tets sharing only an edge: a valid tet mesh whose boundary is not manifold.
  TetMesh bow;
  VertexId a = bow.add_vertex(Vec3(0, 0, 0)), b = bow.add_vertex(Vec3(0, 0, 1));
  VertexId c = bow.add_vertex(Vec3(1, 0, 0)), d = bow.add_vertex(Vec3(0, 1, 0));
  VertexId e = bow.add_vertex(Vec3(-1, 0, 0)), f = bow.add_vertex(Vec3(0, -1, 0));
  bow.add_tet(a, c, d, b);
  bow.add_tet(a, e, f, b);
  bow.validate();
  CHECK_THROWS_WITH(bow.validate({true, true}), Catch::Contains("non-manifold"));
}

TEST_CASE("compact renumbers densely and returns old-to-new maps", "[mesh]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {2, 2, 2});
  std::mt19937 rng(7);
  for (int i = 0; i < 200; ++i) random_edit(m, rng);
  for (int i = 0; i < 10; ++i) m.remove_tet(random_tet(m, rng));
  std::map<std::uint32_t, Vec3> pos;
  for (VertexId v : m.vertices()) pos[v.idx()] = m.rest(v);
  const double vol = m.total_volume();
  const std::size_t nt = m.num_tets(), cap = m.tet_capacity();
  CompactMaps maps = m.compact();
  CHECK(maps.tet.size() == cap);
  CHECK(m.tet_capacity() == nt);
  m.validate();
  CHECK(m.total_volume() == Approx(vol).epsilon(1e-12));
  for (auto& [old, p] : pos) CHECK(m.rest(maps.vertex[old]) == p);
}

TEST_CASE("compact_spatially keeps the mesh and numbers neighbours close", "[mesh]") {
  // A box with edits and dead slots, copied with its vertices and tets in random order (a
  // mesher's scattered numbering), then renumbered along the curve.
  TetMesh box = make_box(Vec3(1, 1, 1), {6, 6, 6});
  std::mt19937 rng(11);
  for (int i = 0; i < 300; ++i) random_edit(box, rng);
  for (TetId t : box.tets())
    if (t.idx() % 7 == 0) box.set_label(t, 3);
  const BoundaryFace bf0 = box.boundary_faces().front();
  box.set_face_tag(bf0.tet, bf0.local, kTagCut);  // tags follow their faces
  box.compact();
  std::vector<std::uint32_t> vperm(box.num_vertices()), tperm(box.num_tets());
  std::iota(vperm.begin(), vperm.end(), 0u);
  std::iota(tperm.begin(), tperm.end(), 0u);
  std::shuffle(vperm.begin(), vperm.end(), rng);
  std::shuffle(tperm.begin(), tperm.end(), rng);
  TetMesh m;
  std::vector<VertexId> to(box.num_vertices());
  for (std::uint32_t i : vperm) to[i] = m.add_vertex(box.rest(VertexId(i)));
  for (std::uint32_t i : tperm) {
    const auto& v = box.tet_vertices(TetId(i));
    const TetId t = m.add_tet(to[v[0].idx()], to[v[1].idx()], to[v[2].idx()], to[v[3].idx()], box.label(TetId(i)));
    for (int f = 0; f < 4; ++f) m.set_face_tag(t, f, box.face_tag(TetId(i), f));
  }
  m.remove_tet(*m.tets().begin());  // a dead slot
  m.discard_change();
  // Each tet by its corner positions (in its vertex order) with its label and face tags.
  auto signature = [](const TetMesh& x) {
    std::multiset<std::vector<double>> out;
    for (TetId t : x.tets()) {
      std::vector<double> s;
      for (VertexId v : x.tet_vertices(t))
        for (int d = 0; d < 3; ++d) s.push_back(x.rest(v)[d]);
      s.push_back(x.label(t));
      for (int f = 0; f < 4; ++f) s.push_back(x.face_tag(t, f));
      out.insert(s);
    }
    return out;
  };
  // Median id span of a tet's corners: how far apart in memory its vertices are (a curve's
  // jumps between octants make a few tets wide, so not the mean).
  auto span = [](const TetMesh& x) {
    std::vector<std::uint32_t> spans;
    for (TetId t : x.tets()) {
      const auto& v = x.tet_vertices(t);
      std::uint32_t lo = v[0].idx(), hi = lo;
      for (VertexId w : v) lo = std::min(lo, w.idx()), hi = std::max(hi, w.idx());
      spans.push_back(hi - lo);
    }
    std::nth_element(spans.begin(), spans.begin() + spans.size() / 2, spans.end());
    return double(spans[spans.size() / 2]);
  };
  const auto before = signature(m);
  const std::size_t nv = m.num_vertices(), nt = m.num_tets(), bf = m.boundary_faces().size();
  const double scattered = span(m), vol = m.total_volume();
  const CompactMaps maps = m.compact_spatially();
  m.validate();
  CHECK(m.num_vertices() == nv);
  CHECK(m.num_tets() == nt);
  CHECK(m.tet_capacity() == nt);
  CHECK(m.boundary_faces().size() == bf);
  CHECK(m.total_volume() == Approx(vol).epsilon(1e-12));
  CHECK(signature(m) == before);
  for (std::uint32_t i = 0; i < vperm.size(); ++i) CHECK(m.rest(maps.vertex[to[i].idx()]) == box.rest(VertexId(i)));
  INFO("median id span of a tet's corners: scattered " << scattered << ", along the curve " << span(m));
  CHECK(span(m) < 0.25 * scattered);
  // Deterministic: the same mesh in another order gets the same numbering.
  TetMesh again = box;
  again.compact_spatially();
  REQUIRE(again.num_vertices() == nv);
  for (VertexId v : again.vertices()) CHECK(again.rest(v) == m.rest(v));
}

TEST_CASE("edits are local: incidence visits per edit do not grow with mesh size", "[mesh][locality]") {
  auto visits_per_edit = [](int n) {
    TetMesh m = make_box(Vec3(1, 1, 1), {n, n, n});
    std::mt19937 rng(3);
    m.reset_counters();
    int edits = 0;
    for (int i = 0; i < 2000; ++i) edits += random_edit(m, rng);
    m.discard_change();
    return double(m.counters().visits) / edits;
  };
  const double small = visits_per_edit(6);    // 1,296 tets
  const double large = visits_per_edit(55);   // 998,250 tets
  INFO("visits per edit: 1.3k tets " << small << ", 1M tets " << large);
  WARN("locality: incidence visits per edit at 1.3k tets = " << small << ", at 1M tets = " << large);
  // Random edits on the small mesh hit the same spots repeatedly (higher degrees), so the
  // large mesh may only be cheaper; what matters is that it is not more expensive.
  CHECK(large < 1.5 * small);
}

TEST_CASE("move_vertex records the move and its tets, backends can interpolate from it", "[mesh][move]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {3, 3, 3});
  m.discard_change();
  // An interior vertex: (1/3, 1/3, 1/3).
  VertexId v;
  for (VertexId x : m.vertices())
    if ((m.rest(x) - Vec3(1.0 / 3, 1.0 / 3, 1.0 / 3)).norm() < 1e-12) v = x;
  REQUIRE(v.is_valid());
  const double vol = m.total_volume();
  // New position: a point inside one of v's own tets, given by barycentric coordinates there.
  const TetId t = m.incident_tets(v)[0];
  const auto tv = m.tet_vertices(t);
  const std::array<double, 4> w = {0.7, 0.1, 0.1, 0.1};
  Vec3 p = Vec3::Zero();
  for (int k = 0; k < 4; ++k) p += w[k] * m.rest(tv[k]);
  CHECK(m.is_move_ok(v, p));
  CHECK_FALSE(m.is_move_ok(v, Vec3(2, 2, 2)));
  m.move_vertex(v, tv, w);
  m.validate({true, true});
  CHECK((m.rest(v) - p).norm() < 1e-15);
  CHECK(m.total_volume() == Approx(vol).epsilon(1e-12));
  const TopologyChange ch = m.take_change();
  REQUIRE(ch.moved_vertices.size() == 1);
  CHECK(ch.moved_vertices[0].vertex == v);
  CHECK(ch.added_vertices.empty());
  CHECK(ch.removed_tets.size() == m.incident_tets(v).size());
  CHECK(ch.added_tets.size() == m.incident_tets(v).size());
}

namespace {
// The mesh up to tet ids: each tet's sorted corners and label, each boundary face's corners
// and tag, every live vertex's rest position.
struct Shape {
  std::vector<std::array<std::uint32_t, 5>> tets;
  std::vector<std::array<std::uint32_t, 4>> faces;
  std::vector<std::pair<std::uint32_t, Vec3>> points;
  bool operator==(const Shape& o) const {
    if (points.size() != o.points.size()) return false;
    for (std::size_t i = 0; i < points.size(); ++i)
      if (points[i].first != o.points[i].first || points[i].second != o.points[i].second) return false;
    return tets == o.tets && faces == o.faces;
  }
};
Shape shape(const TetMesh& m) {
  Shape s;
  for (TetId t : m.tets()) {
    const auto& v = m.tet_vertices(t);
    std::array<std::uint32_t, 5> k{v[0].idx(), v[1].idx(), v[2].idx(), v[3].idx(), std::uint32_t(m.label(t))};
    std::sort(k.begin(), k.begin() + 4);
    s.tets.push_back(k);
  }
  for (const auto& f : m.boundary_faces()) {
    std::array<std::uint32_t, 4> k{f.vertices[0].idx(), f.vertices[1].idx(), f.vertices[2].idx(), f.tag};
    std::sort(k.begin(), k.begin() + 3);
    s.faces.push_back(k);
  }
  for (VertexId v : m.vertices()) s.points.emplace_back(v.idx(), m.rest(v));
  std::sort(s.tets.begin(), s.tets.end());
  std::sort(s.faces.begin(), s.faces.end());
  return s;
}
}  // namespace

TEST_CASE("undo takes logged splits, flips and rewrites back in a later batch", "[mesh][undo]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {3, 3, 3});
  m.discard_change();
  // A cut face on the boundary, so tags have something to keep.
  const TetId t0 = m.tets().front();
  for (int f = 0; f < 4; ++f)
    if (!m.neighbor(t0, f).is_valid()) m.set_face_tag(t0, f, kTagCut);
  const Shape before = shape(m);
  const std::size_t tets_before = m.num_tets(), vertices_before = m.num_vertices();

  m.begin_undo_log();
  const auto& tv = m.tet_vertices(t0);
  const VertexId e = m.split_edge(tv[0], tv[1], 0.3);
  const TetId t1 = m.incident_tets(e).front();
  m.split_tet(t1);
  // A rewrite in place (what a cut's duplication does), on a tet the log has not touched.
  TetId far;
  for (TetId t : m.tets())
    if (m.tet_vertices(t)[0] != e && std::none_of(m.tet_vertices(t).begin(), m.tet_vertices(t).end(),
                                                   [&](VertexId v) { return v == e; }))
      far = t;
  const std::array<VertexId, 4> fv = m.tet_vertices(far);
  const VertexId copy = m.add_vertex_interpolated(std::array{fv[0]}, std::array{1.0});
  m.replace_vertex(far, fv[0], copy);  // the tet leaves its neighbours on that side
  m.replace_vertex(far, copy, fv[0]);  // and comes back
  const TetMesh::UndoLog log = m.end_undo_log();
  CHECK_FALSE(log.empty());
  CHECK_FALSE(log.moved);
  m.validate({true, true});
  CHECK(m.num_tets() > tets_before);
  const TopologyChange first = m.take_change();  // the logged edits are one record

  const auto ids = m.undo(log);
  m.validate({true, true});
  CHECK(shape(m) == before);
  CHECK(m.num_tets() == tets_before);
  CHECK(m.num_vertices() == vertices_before);
  CHECK(ids.size() == log.saved.size());
  for (const auto& [old_id, new_id] : ids) CHECK(m.is_alive(new_id));
  // The record of the undo: the pieces removed, the tets put back added, the new vertices gone.
  const TopologyChange second = m.take_change();
  CHECK(second.added_tets.size() == ids.size());
  CHECK(second.removed_vertices.size() == first.added_vertices.size());
}

TEST_CASE("undo refuses a log that moved a vertex or whose pieces were edited since", "[mesh][undo]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
  m.discard_change();
  m.begin_undo_log();
  const auto tv = m.tet_vertices(m.tets().front());
  m.split_edge(tv[0], tv[1]);
  TetMesh::UndoLog log = m.end_undo_log();
  m.take_change();
  TetMesh edited = m;
  edited.split_edge(tv[2], tv[3]);  // an edge of the split tet's pieces
  CHECK_FALSE(edited.can_undo(log));
  CHECK_THROWS_AS(edited.undo(log), InvalidArgument);
  // Edits that leave the pieces alone (another blade elsewhere) do not stop it.
  TetMesh elsewhere = m;
  // The tet farthest from the logged split.
  const Vec3 at = 0.5 * (m.rest(tv[0]) + m.rest(tv[1]));
  TetId last;
  double far = -1;
  for (TetId t : elsewhere.tets()) {
    Vec3 c = Vec3::Zero();
    for (VertexId v : elsewhere.tet_vertices(t)) c += 0.25 * elsewhere.rest(v);
    if ((c - at).norm() > far) {
      far = (c - at).norm();
      last = t;
    }
  }
  const auto lv = elsewhere.tet_vertices(last);
  bool shared = false;
  for (const auto& [t, v] : log.pieces)
    for (VertexId x : v) shared = shared || x == lv[0] || x == lv[1] || x == lv[2] || x == lv[3];
  REQUIRE_FALSE(shared);
  elsewhere.split_tet(last);
  CHECK(elsewhere.can_undo(log));
  CHECK_NOTHROW(elsewhere.undo(log));
  elsewhere.validate({true, true});
  // A move inside the log.
  TetMesh moved = make_box(Vec3(1, 1, 1), {2, 2, 2});
  moved.discard_change();
  moved.begin_undo_log();
  VertexId inner;
  for (VertexId v : moved.vertices())
    if ((moved.rest(v) - Vec3(0.5, 0.5, 0.5)).norm() < 1e-12) inner = v;
  REQUIRE(inner.is_valid());
  const TetId t = moved.incident_tets(inner).front();
  std::array<VertexId, 4> p = moved.tet_vertices(t);
  moved.move_vertex(inner, p, std::array{0.7, 0.1, 0.1, 0.1});
  const TetMesh::UndoLog mlog = moved.end_undo_log();
  CHECK(mlog.moved);
  CHECK_FALSE(moved.can_undo(mlog));
  CHECK_THROWS_AS(moved.undo(mlog), InvalidArgument);
}
