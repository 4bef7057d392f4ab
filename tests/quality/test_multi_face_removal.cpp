// Multi-face removal: the dynamic program against brute force over every disc of sandwiched
// faces, the mesh's check (what it refuses), and random application on jittered and
// sliver-laden meshes keeping validity, per-label volume, labels and the boundary.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>
#include <random>
#include <set>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "quality/improve.h"
#include "testing/ring.h"
#include "quality/multi_face_removal.h"
#include "testing/mesh_edits.h"

using namespace incise;

namespace {

using Tri = std::array<int, 3>;

using testing::all_triangulations;

// What an edge removal leaves: a ring c_0..c_{n-1} counter-clockwise around the z axis seen from
// w (above), triangulated by `tris`, each triangle with a tet to u (below) and one to w. Every
// triangle is sandwiched between u and w. Vertex ids: ring 0..n-1, u = n, w = n+1.
TetMesh bipyramid(const std::vector<Vec3>& ring, const Vec3& u, const Vec3& w, const std::vector<Tri>& tris) {
  TetMesh m;
  for (const Vec3& p : ring) m.add_vertex(p);
  const VertexId vu = m.add_vertex(u), vw = m.add_vertex(w);
  for (const Tri& t : tris) {
    const VertexId a(t[0]), b(t[1]), c(t[2]);
    m.add_tet(a, b, c, vw);
    m.add_tet(a, c, b, vu);
  }
  m.discard_change();
  return m;
}

// Worst quality of the new tets (rim edge, u, w) of the disc `sub` (triangles with counter-
// clockwise ring indices).
AngleQuality disc_quality(const TetMesh& m, const std::vector<Tri>& sub, VertexId u, VertexId w,
                          const AngleTargets& tg) {
  std::set<std::pair<int, int>> directed;
  for (const Tri& t : sub)
    for (int k = 0; k < 3; ++k) directed.insert({t[k], t[(k + 1) % 3]});
  AngleQuality q;
  for (const auto& [a, b] : directed)
    if (!directed.count({b, a}))
      q.combine(angle_quality(m.rest(VertexId(a)), m.rest(VertexId(b)), m.rest(u), m.rest(w), tg));
  return q;
}

// Best over all edge-connected subsets of `tris` containing triangle `root`.
double brute_force(const TetMesh& m, const std::vector<Tri>& tris, int root, VertexId u, VertexId w,
                   const AngleTargets& tg) {
  const int n = static_cast<int>(tris.size());
  auto shares_edge = [&](int x, int y) {
    int common = 0;
    for (int a : tris[x])
      for (int b : tris[y]) common += a == b;
    return common == 2;
  };
  double best = -1e300;
  for (int mask = 0; mask < (1 << n); ++mask) {
    if (!(mask >> root & 1)) continue;
    // Connected: flood from root inside the mask.
    int reached = 1 << root;
    for (bool grew = true; grew;) {
      grew = false;
      for (int x = 0; x < n; ++x)
        for (int y = 0; y < n; ++y)
          if ((reached >> x & 1) && (mask >> y & 1) && !(reached >> y & 1) && shares_edge(x, y)) {
            reached |= 1 << y;
            grew = true;
          }
    }
    if (reached != mask) continue;
    std::vector<Tri> sub;
    for (int x = 0; x < n; ++x)
      if (mask >> x & 1) sub.push_back(tris[x]);
    best = std::max(best, disc_quality(m, sub, u, w, tg).q);
  }
  return best;
}

// The tet with vertices {t, apex}.
TetId tet_with(const TetMesh& m, const Tri& t, VertexId apex) {
  for (TetId x : m.incident_tets(apex))
    if (m.local_index(x, VertexId(t[0])) >= 0 && m.local_index(x, VertexId(t[1])) >= 0 &&
        m.local_index(x, VertexId(t[2])) >= 0)
      return x;
  return TetId();
}

using FaceKey = std::array<std::uint32_t, 3>;

std::map<FaceKey, std::uint16_t> boundary(const TetMesh& m) {
  std::map<FaceKey, std::uint16_t> out;
  for (const auto& f : m.boundary_faces()) {
    FaceKey k{f.vertices[0].idx(), f.vertices[1].idx(), f.vertices[2].idx()};
    std::sort(k.begin(), k.end());
    out[k] = f.tag;
  }
  return out;
}

std::map<int, double> label_volumes(const TetMesh& m) {
  std::map<int, double> v;
  for (TetId t : m.tets()) v[m.label(t)] += m.volume(t);
  return v;
}

}  // namespace

TEST_CASE("multi-face removal: the dynamic program finds the best disc", "[improve][multiface]") {
  std::mt19937 rng(17);
  const AngleTargets tg;
  ImproveScope scope;
  int applied = 0, meshes = 0;
  for (int n = 3; n <= 8; ++n)
    for (int trial = 0; trial < 12; ++trial) {
      const testing::JitteredRing jr = testing::jittered_ring(n, rng);
      const std::vector<Vec3>& ring = jr.ring;
      const Vec3 &u = jr.below, &w = jr.above;
      // A triangulation whose tets are all positive (the jittered ring need not be convex).
      const auto all = all_triangulations(0, n - 1);
      std::vector<Tri> tris;
      for (int k = 0; k < 20 && tris.empty(); ++k) {
        tris = all[rng() % all.size()];
        try {
          bipyramid(ring, u, w, tris).validate();
        } catch (const InvalidMesh&) {
          tris.clear();
        }
      }
      if (tris.empty()) continue;
      ++meshes;
      const VertexId vu(n), vw(n + 1);
      for (int root = 0; root < n - 2; ++root) {
        TetMesh m = bipyramid(ring, u, w, tris);
        const TetId t = tet_with(m, tris[root], vu);
        const auto plan = best_multi_face_removal(m, t, m.local_index(t, vu), scope);
        REQUIRE(plan);
        CHECK(plan->u == vu);
        CHECK(plan->w == vw);
        CHECK(plan->removed.size() == 2 * plan->faces.size());
        CHECK(plan->after.q == Approx(brute_force(m, tris, root, vu, vw, tg)).margin(1e-12));
        // The reported worst is that of the disc returned.
        std::vector<Tri> disc;
        for (const auto& f : plan->faces) disc.push_back({int(f[0].idx()), int(f[1].idx()), int(f[2].idx())});
        CHECK(disc_quality(m, disc, vu, vw, tg).q == Approx(plan->after.q).margin(1e-12));
        // Where every new tet is positive, the mesh takes it: m+2 tets for 2m, volume kept.
        if (plan->after.q > 0.01 && m.is_multi_face_removal_ok(plan->u, plan->w, plan->faces)) {
          const double vol = m.total_volume();
          const auto added = m.remove_faces(plan->u, plan->w, plan->faces);
          CHECK(added.size() == plan->faces.size() + 2);
          CHECK(m.num_tets() == 2 * tris.size() - plan->faces.size() + 2);
          REQUIRE_NOTHROW(m.validate({true, true}));
          CHECK(m.total_volume() == Approx(vol).epsilon(1e-12));
          ++applied;
        }
      }
    }
  CHECK(meshes > 50);
  CHECK(applied > 50);
}

TEST_CASE("multi-face removal: the mesh refuses what is not a sandwiched disc", "[mesh][multiface]") {
  // A fan of five triangles around an inner vertex x, sandwiched between u and w.
  TetMesh m;
  std::vector<VertexId> c;
  for (int i = 0; i < 5; ++i) c.push_back(m.add_vertex(Vec3(std::cos(2 * M_PI * i / 5), std::sin(2 * M_PI * i / 5), 0)));
  // x off the axis so that the axis u-w sees every rim edge of the discs tried below from inside.
  const VertexId x = m.add_vertex(Vec3(0.1, -0.05, 0.02)), u = m.add_vertex(Vec3(0, 0, -1)), w = m.add_vertex(Vec3(0, 0, 1));
  std::vector<std::array<VertexId, 3>> fan;
  for (int i = 0; i < 5; ++i) {
    fan.push_back({x, c[i], c[(i + 1) % 5]});
    m.add_tet(x, c[i], c[(i + 1) % 5], w);
    m.add_tet(x, c[(i + 1) % 5], c[i], u);
  }
  m.discard_change();
  REQUIRE_NOTHROW(m.validate({true, true}));
  // All five: x is inside the disc and would lose all its tets.
  CHECK_FALSE(m.is_multi_face_removal_ok(u, w, fan));
  CHECK_THROWS_AS(m.remove_faces(u, w, fan), InvalidArgument);
  // A repeated face; apexes joined by an edge already (u-x), or not apexes of the face at all.
  const std::array<VertexId, 3> twice[2] = {fan[0], fan[0]};
  CHECK_FALSE(m.is_multi_face_removal_ok(u, w, twice));
  CHECK_FALSE(m.is_multi_face_removal_ok(u, x, std::span(fan).first(2)));
  CHECK_FALSE(m.is_multi_face_removal_ok(u, c[3], std::span(fan).first(1)));
  // Two faces that share only x: not a disc with every vertex on one rim.
  const std::array<VertexId, 3> apart[2] = {fan[0], fan[2]};
  CHECK_FALSE(m.is_multi_face_removal_ok(u, w, apart));
  // Labels: one tet of another label stops it.
  {
    TetMesh l = m;
    for (TetId t : l.incident_tets(w))
      if (l.local_index(t, c[3]) >= 0 && l.local_index(t, c[4]) >= 0) l.set_label(t, 7);
    CHECK_FALSE(l.is_multi_face_removal_ok(u, w, std::span(fan).subspan(2, 3)));
    CHECK(l.is_multi_face_removal_ok(u, w, std::span(fan).first(3)));
  }
  // Four of the five: x is on the rim; 8 tets become 6. The apexes may come in either order
  // (the orientation comes from the tets).
  CHECK(m.is_multi_face_removal_ok(w, u, std::span(fan).first(4)));
  const double vol = m.total_volume();
  const auto added = m.remove_faces(u, w, std::span(fan).first(4));
  CHECK(added.size() == 6);
  CHECK(m.num_tets() == 8);
  REQUIRE_NOTHROW(m.validate({true, true}));
  CHECK(m.total_volume() == Approx(vol).epsilon(1e-12));
  // Each face is grown once, so the DP's discs are trees of faces; one that holds the whole fan
  // has the closing edge's two tets, facing opposite ways: never positive, and refused.
  TetMesh again;
  for (int i = 0; i < 5; ++i) again.add_vertex(m.rest(c[i]));
  for (VertexId v : {x, u, w}) again.add_vertex(m.rest(v));
  for (int i = 0; i < 5; ++i) {
    again.add_tet(VertexId(5), VertexId(i), VertexId((i + 1) % 5), VertexId(7));
    again.add_tet(VertexId(5), VertexId((i + 1) % 5), VertexId(i), VertexId(6));
  }
  again.discard_change();
  for (TetId t : again.incident_tets(VertexId(6))) {
    const auto plan = best_multi_face_removal(again, t, again.local_index(t, VertexId(6)), ImproveScope{});
    REQUIRE(plan);
    UNSCOPED_INFO("fan: " << plan->faces.size() << " faces, q " << plan->after.q);
    CHECK((plan->faces.size() < 5 || plan->after.q < 0));
    CHECK(again.is_multi_face_removal_ok(plan->u, plan->w, plan->faces) == (plan->after.q > 0));
  }
}

TEST_CASE("multi-face removal: random application keeps the mesh valid, volumes, labels and boundary",
          "[improve][multiface]") {
  std::vector<TetMesh> meshes;
  meshes.push_back(make_box(Vec3(1, 1, 1), {4, 4, 4}));
  testing::jitter(meshes.back(), 0.3, 4);
  meshes.push_back(make_box(Vec3(1, 2, 1), {3, 6, 3}));  // two labels, the interface at y = 1
  testing::jitter(meshes.back(), 0.25, 8);
  for (TetId t : meshes.back().tets()) {
    double y = 0;
    for (VertexId v : meshes.back().tet_vertices(t)) y += meshes.back().rest(v).y() / 4;
    if (y < 1) meshes.back().set_label(t, 5);
  }
  {
    TetMesh s = make_box(Vec3(1, 1, 1), {3, 3, 3});  // sliver-laden: random splits and flips
    std::mt19937 rng(5);
    for (int i = 0; i < 300; ++i) testing::random_edit(s, rng);
    testing::jitter(s, 0.2, 3);
    meshes.push_back(std::move(s));
  }
  meshes.push_back(make_ellipsoid(Vec3(1, 0.7, 0.5), 3));
  testing::jitter(meshes.back(), 0.3, 2);
  std::uint32_t seed = 1;
  for (TetMesh& m : meshes) {
    CAPTURE(seed);
    std::mt19937 rng(seed++);
    m.discard_change();
    const auto vols = label_volumes(m);
    const auto bnd = boundary(m);
    ImproveScope scope;
    int applied = 0, large = 0;
    for (int i = 0; i < 2000; ++i) {
      const TetId t = testing::random_tet(m, rng);
      const auto plan = best_multi_face_removal(m, t, static_cast<int>(rng() % 4), scope);
      if (!plan || !m.is_multi_face_removal_ok(plan->u, plan->w, plan->faces)) continue;
      const int lab = m.label(t);
      const std::size_t before = m.num_tets();
      const auto added = m.remove_faces(plan->u, plan->w, plan->faces);
      REQUIRE_NOTHROW(m.validate());
      CHECK(m.num_tets() == before - plan->faces.size() + 2);
      for (TetId a : added) CHECK(m.label(a) == lab);
      ++applied;
      large += plan->faces.size() >= 3;
    }
    INFO(applied << " removals, " << large << " of 3 faces or more");
    CHECK(applied > 100);
    CHECK(large > 5);
    REQUIRE_NOTHROW(m.validate({true, true}));
    const auto vols_after = label_volumes(m);
    REQUIRE(vols_after.size() == vols.size());
    for (const auto& [lab, v] : vols) CHECK(vols_after.at(lab) == Approx(v).epsilon(1e-9));
    CHECK(boundary(m) == bnd);
    // One record: what the backends consume.
    const TopologyChange ch = m.take_change();
    CHECK(ch.added_vertices.empty());
    CHECK(ch.removed_vertices.empty());
    CHECK(!ch.removed_tets.empty());
  }
}

TEST_CASE("multi-face removal in the pass: counted, never worse, off when asked", "[improve][multiface]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {6, 6, 6});
  testing::jitter(m, 0.4, 1);
  m.discard_change();
  TetMesh off = m;
  ImproveOptions o;
  o.smoothing = false;  // flips only: what multi-face removal adds shows directly
  const ImproveReport on = improve(m, o);
  REQUIRE_NOTHROW(m.validate({true, true}));
  CHECK(on.multi_face_removals > 0);
  CHECK(on.min_dihedral_after >= on.min_dihedral_before);
  CHECK(on.max_dihedral_after <= on.max_dihedral_before);
  o.multi_face_removal = false;
  const ImproveReport no = improve(off, o);
  CHECK(no.multi_face_removals == 0);
  UNSCOPED_INFO("flips only, min dihedral with / without: " << on.min_dihedral_after << " / " << no.min_dihedral_after);
}
