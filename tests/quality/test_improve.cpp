// Invariants of the improvement pass on generated, jittered, sliver-laden, two-label,
// stuffed and rescaled meshes: valid, never a worse worst element, labels, boundary faces and
// their tags, interfaces and per-label volumes kept, boundary vertices on their planes.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <set>

#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "mesh/isosurface_stuffing.h"
#include "quality/dihedral_objective.h"
#include "quality/improve.h"
#include "quality/insertion.h"
#include "quality/metrics.h"
#include "quality/quality_cache.h"
#include "testing/mesh_edits.h"

using namespace incise;

namespace {

#if defined(__SANITIZE_ADDRESS__)
constexpr int kCells = 3;
#else
constexpr int kCells = 5;
#endif

using FaceKey = std::array<std::uint32_t, 3>;

FaceKey key(std::array<VertexId, 3> f) {
  FaceKey k{f[0].idx(), f[1].idx(), f[2].idx()};
  std::sort(k.begin(), k.end());
  return k;
}

// Everything improvement must keep.
struct Snapshot {
  std::map<FaceKey, std::uint16_t> boundary;           // boundary faces and their tags
  std::map<FaceKey, std::pair<int, int>> interfaces;   // faces between labels, label pair
  std::map<int, double> volume;                        // per label
  std::map<FaceKey, std::pair<Vec3, Vec3>> planes;     // boundary face: a point and unit normal
  std::map<std::uint16_t, std::pair<double, int>> boundary_area;  // per tag: area, faces
  AngleQuality worst;
  double min_dih = 180, max_dih = 0;
};

std::map<std::uint16_t, std::pair<double, int>> boundary_by_tag(const TetMesh& m, const Snapshot& s);

Snapshot snapshot(const TetMesh& m) {
  Snapshot s;
  for (TetId t : m.tets()) {
    s.volume[m.label(t)] += m.volume(t);
    s.worst.combine(angle_quality(m, t, AngleTargets{}));
    const TetQuality q = tet_quality(m, t);
    s.min_dih = std::min(s.min_dih, q.min_dihedral);
    s.max_dih = std::max(s.max_dih, q.max_dihedral);
    for (int f = 0; f < 4; ++f) {
      const TetId u = m.neighbor(t, f);
      const auto fv = m.face_vertices(t, f);
      if (!u.is_valid()) {
        s.boundary[key(fv)] = m.face_tag(t, f);
        const Vec3 n = (m.rest(fv[1]) - m.rest(fv[0])).cross(m.rest(fv[2]) - m.rest(fv[0])).normalized();
        s.planes[key(fv)] = {m.rest(fv[0]), n};
      } else if (m.label(u) != m.label(t)) {
        s.interfaces[key(fv)] = {std::min(m.label(t), m.label(u)), std::max(m.label(t), m.label(u))};
      }
    }
  }
  s.boundary_area = boundary_by_tag(m, s);
  return s;
}

// Area of the boundary per tag, and its face count per tag.
std::map<std::uint16_t, std::pair<double, int>> boundary_by_tag(const TetMesh& m, const Snapshot& s) {
  std::map<std::uint16_t, std::pair<double, int>> out;
  for (const auto& [k, tag] : s.boundary) {
    const Vec3 a = m.rest(VertexId(k[0])), b = m.rest(VertexId(k[1])), c = m.rest(VertexId(k[2]));
    out[tag].first += 0.5 * (b - a).cross(c - a).norm();
    ++out[tag].second;
  }
  return out;
}

// added_faces: boundary faces boundary insertions added (two each: one face split in three).
void check_kept(const TetMesh& m, const Snapshot& before, double scale, int added_faces = 0) {
  REQUIRE_NOTHROW(m.validate());
  const Snapshot after = snapshot(m);
  // The boundary may be re-triangulated only within its flat parts (boundary flips) and its
  // vertices may slide only within them: every new boundary face lies in the plane of an old
  // face with the same tag at one of its vertices, and the area and face count per tag stay.
  std::map<std::uint32_t, std::vector<FaceKey>> old_faces_at;
  for (const auto& [k, tag] : before.boundary)
    for (auto v : k) old_faces_at[v].push_back(k);
  int off_plane = 0;
  for (const auto& [k, tag] : after.boundary) {
    bool found = false;
    for (auto v : k)
      for (const FaceKey& g : old_faces_at[v]) {
        if (found || before.boundary.at(g) != tag) continue;
        const auto& [p, n] = before.planes.at(g);
        double d = 0;
        for (auto w : k) d = std::max(d, std::abs(n.dot(m.rest(VertexId(w)) - p)));
        found = d <= 1e-9 * scale;
      }
    off_plane += !found;
  }
  CHECK(off_plane == 0);
  const auto area_before = before.boundary_area, area_after = boundary_by_tag(m, after);
  REQUIRE(area_after.size() == area_before.size());
  for (const auto& [tag, ac] : area_before) {
    CHECK(std::abs(area_after.at(tag).first - ac.first) <= 1e-9 * ac.first);
    // Flips keep the face count; a contraction of a boundary vertex removes two faces.
    CHECK(area_after.at(tag).second <= ac.second + added_faces);
  }
  CHECK(after.interfaces == before.interfaces);
  REQUIRE(after.volume.size() == before.volume.size());
  for (const auto& [label, v] : before.volume) CHECK(std::abs(after.volume.at(label) - v) <= 1e-9 * std::abs(v));
  CHECK(after.worst.q >= before.worst.q);
  // The extreme angles never get worse, except within the targets (35 and 135 degrees).
  CHECK(after.min_dih >= std::min(before.min_dih, 35.0) - 1e-9);
  CHECK(after.max_dih <= std::max(before.max_dih, 135.0) + 1e-9);
}

TetMesh two_labels(TetMesh m) {
  for (TetId t : m.tets()) {
    Vec3 c = Vec3::Zero();
    for (VertexId v : m.tet_vertices(t)) c += m.rest(v) / 4;
    if (c.x() < 0.5 * kCells / 5.0) m.set_label(t, 2);
  }
  return m;
}

void scale_mesh(TetMesh& m, double s) {
  for (VertexId v : m.vertices()) m.set_rest(v, m.rest(v) * s);
}

// Runs improve and checks the invariants and the reported figures.
ImproveReport run_and_check(TetMesh& m, double scale, ImproveOptions opt = {}) {
  m.discard_change();
  const Snapshot before = snapshot(m);
  opt.time_limit_s = 60;  // the checks, not the clock, decide
  const ImproveReport rep = improve(m, opt);
  UNSCOPED_INFO("dihedral " << rep.min_dihedral_before << ".." << rep.max_dihedral_before << " -> "
                            << rep.min_dihedral_after << ".." << rep.max_dihedral_after << ", tets " << rep.tets_before
                            << " -> " << rep.tets_after << ", flips " << rep.flips23 << "/" << rep.flips32 << "/"
                            << rep.flips44 << "/" << rep.edge_removals << ", moves " << rep.smoothing_moves << ", "
                            << rep.seconds << " s");
  check_kept(m, before, scale, 2 * rep.boundary_insertions);
  CHECK(rep.min_dihedral_before == Approx(before.min_dih));
  CHECK(rep.min_dihedral_after >= std::min(rep.min_dihedral_before, 35.0));
  CHECK(rep.max_dihedral_after <= std::max(rep.max_dihedral_before, 135.0));
  CHECK(rep.min_radius_ratio_after >= rep.min_radius_ratio_before - 1e-12);
  CHECK(rep.tets_after == m.num_tets());
  // One TopologyChange for the pass, listing the moved vertices the report lists.
  const TopologyChange ch = m.take_change();
  // (Those still alive: a contraction may remove a vertex smoothing moved earlier in the pass;
  // the record then lists it as moved and removed, which consumers apply in that order.)
  std::set<std::uint32_t> moved;
  for (const auto& o : ch.moved_vertices)
    if (m.is_alive(o.vertex)) moved.insert(o.vertex.idx());
  std::set<std::uint32_t> removed;
  for (VertexId v : ch.removed_vertices) removed.insert(v.idx());
  CHECK(removed.size() == static_cast<std::size_t>(rep.contractions));
  std::set<std::uint32_t> reported;
  for (VertexId v : rep.moved_vertices) reported.insert(v.idx());
  CHECK(moved == reported);
  CHECK(ch.added_vertices.size() == static_cast<std::size_t>(rep.insertions));
  CHECK(double(rep.tets_after) <= opt.max_growth * double(rep.tets_before));
  return rep;
}

}  // namespace

TEST_CASE("improve: jittered box, one and two labels, three scales", "[improve]") {
  for (double scale : {1.0, 1e-6, 1e6})
    for (bool labels : {false, true}) {
      CAPTURE(scale, labels);
      TetMesh m = make_box(Vec3(1, 1, 1) * kCells / 5.0, {kCells, kCells, kCells});
      if (labels) m = two_labels(std::move(m));
      testing::jitter(m, 0.35, 11);
      scale_mesh(m, scale);
      const ImproveReport rep = run_and_check(m, scale);
      CHECK(rep.flips23 + rep.flips32 + rep.flips44 + rep.edge_removals > 0);
      CHECK(rep.smoothing_moves > 0);
      if (!labels) CHECK(rep.min_dihedral_after > rep.min_dihedral_before + 1);  // an interface vertex stays
    }
}

TEST_CASE("improve: sliver-laden mesh from random splits and flips", "[improve][long]") {
  TetMesh m = make_box(Vec3(1, 1, 1), {3, 3, 3});
  std::mt19937 rng(5);
  for (int i = 0; i < 300; ++i) testing::random_edit(m, rng);
  testing::jitter(m, 0.2, 3);
  TetMesh with_insertion = m;
  const ImproveReport rep = run_and_check(m, 1.0);
  CHECK(rep.min_dihedral_after > rep.min_dihedral_before);
  // Insertion where flips and smoothing are stuck: never worse, within the growth bound.
  ImproveOptions o;
  o.insertion = true;
  o.max_growth = 1.2;
  const ImproveReport ins = run_and_check(with_insertion, 1.0, o);
  CHECK(ins.insertions > 0);
  // Insertion (and its radius-ratio floor) starts once the sweeps without it, the run above,
  // have converged, and never makes the worst tet worse: at least as good at both ends.
  CHECK(ins.min_dihedral_after >= rep.min_dihedral_after);
  CHECK(ins.max_dihedral_after <= rep.max_dihedral_after);
}

TEST_CASE("improve: cavity insertion lifts the sample elephant's worst tets further", "[improve][insertion]") {
  TetMesh without = read_tet_mesh(std::string(INCISE_SOURCE_DIR) + "/samples/elephant.msh");
  TetMesh with = without;
  const ImproveReport a = run_and_check(without, 1.0);
  ImproveOptions o;
  o.insertion = true;
  const ImproveReport b = run_and_check(with, 1.0, o);
  CHECK(b.insertions > 0);
  CHECK(b.boundary_insertions > 0);
  // Surface exact (no curved sliding): the worst dihedral rises beyond what the rest reaches.
  CHECK(b.min_dihedral_after > a.min_dihedral_after + 2);
  CHECK(b.max_dihedral_after < a.max_dihedral_after - 2);
}

TEST_CASE("improve: holes, pinched vertices and cut-tagged planes (what a cut leaves)", "[improve]") {
  // Tets removed at the boundary leave non-manifold edges and vertices; a plane of faces tagged
  // kTagCut (the box's x = 0 side) must stay on its plane with its tag.
  TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
  for (TetId t : m.tets())
    for (int f = 0; f < 4; ++f)
      if (!m.neighbor(t, f).is_valid()) {
        bool on_x0 = true;
        for (VertexId v : m.face_vertices(t, f)) on_x0 = on_x0 && m.rest(v).x() == 0;
        if (on_x0) m.set_face_tag(t, f, kTagCut);
      }
  std::mt19937 rng(13);
  for (int i = 0; i < 200; ++i) testing::random_edit(m, rng, true);
  testing::jitter(m, 0.3, 8);
  const ImproveReport rep = run_and_check(m, 1.0);
  CHECK(rep.min_dihedral_after > rep.min_dihedral_before);
  std::mt19937 rng2(14);
  std::vector<TetId> seeds;
  for (int i = 0; i < 10; ++i) seeds.push_back(testing::random_tet(m, rng2));
  m.discard_change();
  const Snapshot before = snapshot(m);
  improve_local(m, seeds);
  check_kept(m, before, 1.0);
}

TEST_CASE("improve: ellipsoid and stuffing output (curved surface stays put)", "[improve]") {
  TetMesh e = make_ellipsoid(Vec3(1, 0.7, 0.5), kCells / 2 + 1);
  testing::jitter(e, 0.3, 2);
  run_and_check(e, 1.0);
  StuffingOptions so;
  so.cell_size = 0.25;
  TetMesh s = isosurface_stuffing([](const Vec3& p) { return p.norm() - 1; }, Vec3(-1.2, -1.2, -1.2),
                                  Vec3(1.2, 1.2, 1.2), so);
  const ImproveReport rep = run_and_check(s, 1.0);
  CHECK(rep.min_dihedral_after >= rep.min_dihedral_before);
}

TEST_CASE("improve: flips only, smoothing only, frozen vertices", "[improve]") {
  TetMesh base = make_box(Vec3(1, 1, 1), {4, 4, 4});
  testing::jitter(base, 0.35, 4);
  {
    TetMesh m = base;
    ImproveOptions o;
    o.smoothing = false;
    const ImproveReport r = run_and_check(m, 1.0, o);
    CHECK(r.smoothing_moves == 0);
    CHECK(r.moved_vertices.empty());
  }
  {
    TetMesh m = base;
    ImproveOptions o;
    o.flips = false;
    o.collapse = false;
    const ImproveReport r = run_and_check(m, 1.0, o);
    CHECK(r.flips23 + r.flips32 + r.flips44 + r.edge_removals == 0);
    CHECK(r.tets_after == r.tets_before);
  }
  {
    TetMesh m = base;
    const std::vector<VertexId> frozen = m.vertices();
    ImproveOptions o;
    o.frozen = frozen;
    std::vector<Vec3> pos;
    for (VertexId v : frozen) pos.push_back(m.rest(v));
    const ImproveReport r = run_and_check(m, 1.0, o);
    CHECK(r.smoothing_moves == 0);
    for (std::size_t i = 0; i < frozen.size(); ++i) CHECK(m.rest(frozen[i]) == pos[i]);
  }
  {
    // Boundary sliding off: boundary vertices stay exactly where they were.
    TetMesh m = base;
    ImproveOptions o;
    o.move_surface = false;
    std::map<std::uint32_t, Vec3> pos;
    for (const auto& f : m.boundary_faces())
      for (VertexId v : f.vertices) pos[v.idx()] = m.rest(v);
    run_and_check(m, 1.0, o);
    for (const auto& [v, p] : pos) CHECK(m.rest(VertexId(v)) == p);
  }
}

TEST_CASE("improve: flat boundary and interface vertices slide in their plane, crease vertices on their line", "[improve]") {
  // Two labels split at x = 0.5; boundary vertices jittered inside their box faces, vertices on
  // box edges along the edge, interface vertices inside the plane x = 0.5: sliding has work.
  TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
  for (TetId t : m.tets()) {
    Vec3 c = Vec3::Zero();
    for (VertexId v : m.tet_vertices(t)) c += m.rest(v) / 4;
    if (c.x() < 0.5) m.set_label(t, 2);
  }
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  auto on_plane = [](const Vec3& p, int k) { return p[k] == 0 || p[k] == 1 || (k == 0 && p[k] == 0.5); };
  for (VertexId v : m.vertices()) {
    Vec3 p = m.rest(v);
    int on = 0;
    for (int k = 0; k < 3; ++k) on += on_plane(p, k);
    if (on != 1 && on != 2) continue;  // corners stay; edges slide along their line
    for (int k = 0; k < 3; ++k)
      if (!on_plane(p, k)) p[k] += 0.25 * u(rng);
    m.set_rest(v, p);
  }
  REQUIRE_NOTHROW(m.validate());
  const ImproveReport r = run_and_check(m, 1.0);
  int boundary_moved = 0, interface_moved = 0, crease_moved = 0;
  std::set<std::uint32_t> on_boundary;
  for (const auto& f : m.boundary_faces())
    for (VertexId v : f.vertices) on_boundary.insert(v.idx());
  auto outer = [](double x) { return std::abs(x) < 1e-12 || std::abs(x - 1) < 1e-12; };
  for (VertexId v : r.moved_vertices) {
    const Vec3 p = m.rest(v);
    boundary_moved += on_boundary.count(v.idx()) > 0;
    interface_moved += p.x() == Approx(0.5).margin(1e-12) && !on_boundary.count(v.idx());
    crease_moved += (outer(p.x()) + outer(p.y()) + outer(p.z())) == 2;  // on a box edge
  }
  CHECK(boundary_moved > 0);
  CHECK(crease_moved > 0);
  CHECK(interface_moved > 0);
  CHECK(r.boundary_flips > 0);
  CHECK(r.min_dihedral_after > r.min_dihedral_before + 5);
}

TEST_CASE("improve: sliding on a curved surface stays on the old surface", "[improve]") {
  StuffingOptions so;
  so.cell_size = 0.25;
  TetMesh m = isosurface_stuffing([](const Vec3& p) { return p.norm() - 1; }, Vec3(-1.2, -1.2, -1.2),
                                  Vec3(1.2, 1.2, 1.2), so);
  m.discard_change();
  const Snapshot before = snapshot(m);
  // Boundary vertices lie on the unit sphere up to the stuffing's own snapping.
  double dev_before = 0;
  std::set<std::uint32_t> on_boundary;
  for (const auto& [k, tag] : before.boundary)
    for (auto v : k) on_boundary.insert(v);
  for (auto v : on_boundary) dev_before = std::max(dev_before, std::abs(m.rest(VertexId(v)).norm() - 1));
  std::map<std::uint32_t, Vec3> old_pos;
  for (VertexId v : m.vertices()) old_pos[v.idx()] = m.rest(v);
  ImproveOptions o;
  o.slide_curved = true;
  const ImproveReport r = improve(m, o);
  REQUIRE_NOTHROW(m.validate());
  const Snapshot after = snapshot(m);
  CHECK(after.boundary.size() == before.boundary.size());
  CHECK(after.worst.q >= before.worst.q);
  CHECK(r.min_dihedral_after > r.min_dihedral_before);
  // Volume within 1% (the chords move by at most the sagitta of a 0.25-cell disc on a unit sphere).
  CHECK(std::abs(after.volume.at(1) - before.volume.at(1)) < 1e-2 * before.volume.at(1));
  // A vertex slides once per pass, onto its old faces, so it leaves the unit sphere by at
  // most the sagitta of its disc: (disc radius)^2 / 2 <= (longest boundary edge)^2 / 2.
  double lmax = 0;
  for (const auto& [k, tag] : before.boundary)
    for (int i = 0; i < 3; ++i) lmax = std::max(lmax, (old_pos[k[i]] - old_pos[k[(i + 1) % 3]]).norm());
  int slid = 0;
  double dev_after = 0;
  for (auto v : on_boundary) {
    slid += m.rest(VertexId(v)) != old_pos[v];
    dev_after = std::max(dev_after, std::abs(m.rest(VertexId(v)).norm() - 1));
  }
  UNSCOPED_INFO("sphere deviation " << dev_before << " -> " << dev_after << ", slid " << slid);
  CHECK(dev_after <= dev_before + lmax * lmax / 2);
  CHECK(slid > 0);
}

TEST_CASE("improve_local: only the seeds' rings change, never for the worse", "[improve]") {
  TetMesh m = make_box(Vec3(1, 1, 1) * 2, {2 * kCells, 2 * kCells, 2 * kCells});
  testing::jitter(m, 0.35, 21);
  m.discard_change();
  const Snapshot before = snapshot(m);
  // Seeds: the tets around one interior vertex.
  VertexId centre;
  double best = 1e300;
  for (VertexId v : m.vertices())
    if ((m.rest(v) - Vec3(1, 1, 1)).norm() < best) best = (m.rest(v) - Vec3(1, 1, 1)).norm(), centre = v;
  const auto inc = m.incident_tets(centre);
  const std::vector<TetId> seeds(inc.begin(), inc.end());
  // The region as the contract defines it: seeds plus two vertex rings.
  std::set<std::uint32_t> region;
  std::vector<TetId> frontier = seeds;
  for (TetId t : seeds) region.insert(t.idx());
  for (int r = 0; r < 2; ++r) {
    std::vector<TetId> next;
    for (TetId t : frontier)
      for (VertexId v : m.tet_vertices(t))
        for (TetId u : m.incident_tets(v))
          if (region.insert(u.idx()).second) next.push_back(u);
    frontier = next;
  }
  std::map<std::uint32_t, std::array<VertexId, 4>> outside;
  std::map<std::uint32_t, Vec3> outside_pos;
  for (TetId t : m.tets())
    if (!region.count(t.idx())) {
      outside[t.idx()] = m.tet_vertices(t);
      for (VertexId v : m.tet_vertices(t)) outside_pos[v.idx()] = m.rest(v);
    }
  ImproveOptions o;
  o.max_work = 500;
  const ImproveReport r = improve_local(m, seeds, o);
  check_kept(m, before, 1.0);
  CHECK(r.tets_before == region.size());
  CHECK(r.min_dihedral_after >= std::min(r.min_dihedral_before, 35.0));
  CHECK(r.max_dihedral_after <= std::max(r.max_dihedral_before, 135.0));
  CHECK(r.flips23 + r.flips32 + r.flips44 + r.edge_removals + r.smoothing_moves > 0);
  for (const auto& [t, v] : outside) {
    REQUIRE(m.is_alive(TetId(t)));
    CHECK(m.tet_vertices(TetId(t)) == v);
  }
  for (const auto& [v, p] : outside_pos) CHECK(m.rest(VertexId(v)) == p);
  // A work cap of one operation stops early and says so.
  TetMesh m2 = make_box(Vec3(1, 1, 1), {3, 3, 3});
  testing::jitter(m2, 0.4, 1);
  ImproveOptions one;
  one.max_work = 1;
  const std::vector<TetId> all = m2.tets();
  CHECK(improve_local(m2, all, one).budget_exhausted);
}

TEST_CASE("improve_local with a quality cache: the same mesh as without, over passes and edits between them",
          "[improve]") {
  // The cutter's steps share one AngleQualityCache between their passes: an entry must stand
  // for its tet only while the tet is the same (ids come back as other tets, vertices move).
  TetMesh plain = make_box(Vec3(1, 1, 1) * 2, {2 * kCells, 2 * kCells, 2 * kCells});
  testing::jitter(plain, 0.35, 7);
  plain.discard_change();
  TetMesh cached = plain;
  AngleQualityCache cache;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> shake(-0.02, 0.02);
  for (int pass = 0; pass < 12; ++pass) {
    // Seeds: the tets around a vertex that walks across the box, so that regions overlap.
    const Vec3 at = Vec3(0.4, 0.5, 0.6) + 0.1 * pass * Vec3(1, 0.8, 0.6);
    auto seeds_of = [&](const TetMesh& m) {
      VertexId centre;
      double best = 1e300;
      for (VertexId v : m.vertices())
        if ((m.rest(v) - at).norm() < best) best = (m.rest(v) - at).norm(), centre = v;
      const auto inc = m.incident_tets(centre);
      return std::vector<TetId>(inc.begin(), inc.end());
    };
    ImproveOptions o;
    o.max_work = 40;
    o.rings = 1;
    const ImproveReport a = improve_local(plain, seeds_of(plain), o);
    o.quality_cache = &cache;
    const ImproveReport b = improve_local(cached, seeds_of(cached), o);
    CHECK(a.work == b.work);
    CHECK(a.min_dihedral_after == b.min_dihedral_after);
    plain.discard_change();
    cached.discard_change();
    // An edit outside the pass: interior vertices near the next region move a little.
    for (VertexId v : plain.vertices()) {
      const Vec3 p = plain.rest(v);
      const bool inside = (p.array() > 0.01).all() && (p.array() < 1.99).all();
      if (!inside || (p - at).norm() > 0.5) continue;
      const Vec3 d(shake(rng), shake(rng), shake(rng));
      plain.set_rest(v, p + d);
      cached.set_rest(v, p + d);
    }
  }
  REQUIRE(plain.num_tets() == cached.num_tets());
  for (TetId t : plain.tets()) {
    REQUIRE(cached.is_alive(t));
    CHECK(plain.tet_vertices(t) == cached.tet_vertices(t));
  }
  for (VertexId v : plain.vertices()) CHECK(plain.rest(v) == cached.rest(v));
  // And its figures are angle_quality's now, for any targets asked.
  const AngleTargets other{20, 150, 1.0};
  for (TetId t : cached.tets()) {
    const AngleQuality q = cache.get(cached, t, other), r = angle_quality(cached, t, other);
    REQUIRE(q.q == r.q);
    REQUIRE(q.min_dihedral == r.min_dihedral);
    REQUIRE(q.radius_ratio == r.radius_ratio);
  }
}

TEST_CASE("improve with insertion: the record carries affine fields exactly", "[improve][insertion]") {
  // Consumers apply added vertices first, then moves, each in order, interpolating every
  // per-vertex field. The pass smooths before it inserts, so an insertion next to a moved
  // vertex must be recorded at the positions the batch started from. With an affine field
  // f(x) = A x + c given at the old rest positions, replaying the record as a consumer does
  // must give f(rest) at every vertex afterwards.
  TetMesh m = read_tet_mesh(std::string(INCISE_SOURCE_DIR) + "/samples/elephant.msh");
  m.discard_change();
  Eigen::Matrix3d A;
  A << 0.3, -0.2, 0.1, 0.05, 0.4, -0.3, 0.2, 0.1, -0.25;
  const Vec3 c(1, -2, 0.5);
  const auto f = [&](const Vec3& x) -> Vec3 { return A * x + c; };
  std::vector<Vec3> field(m.vertex_capacity());
  for (VertexId v : m.vertices()) field[v.idx()] = f(m.rest(v));
  ImproveOptions o;
  o.insertion = true;
  o.time_limit_s = 60;
  const ImproveReport rep = improve(m, o);
  REQUIRE(rep.insertions > 0);
  REQUIRE(rep.smoothing_moves > 0);
  const TopologyChange ch = m.take_change();
  field.resize(m.vertex_capacity());
  const auto interpolate = [&](const VertexOrigin& r) {
    Vec3 s = Vec3::Zero();
    for (int k = 0; k < 4; ++k)
      if (r.parents[k].is_valid() && r.weights[k] != 0) s += r.weights[k] * field[r.parents[k].idx()];
    field[r.vertex.idx()] = s;
  };
  for (const VertexOrigin& r : ch.added_vertices) interpolate(r);
  for (const VertexOrigin& r : ch.moved_vertices) interpolate(r);
  double worst = 0, scale = 0;
  for (VertexId v : m.vertices()) {
    worst = std::max(worst, (field[v.idx()] - f(m.rest(v))).norm());
    scale = std::max(scale, f(m.rest(v)).norm());
  }
  INFO("worst field error " << worst << " of " << scale);
  CHECK(worst <= 1e-9 * scale);
}

TEST_CASE("insertion into the star of a sharp boundary edge shares its angle anew", "[improve][insertion]") {
  // Three tets around the boundary edge a-b (the z axis), its interior angle 120 degrees split
  // 10 / 55 / 55: every vertex is on the boundary, so only a vertex inside helps, and only in a
  // cavity holding all three tets (the 10-degree tet alone leaves that wedge to its new tets).
  TetMesh m;
  const VertexId a = m.add_vertex(Vec3(0, 0, 0)), b = m.add_vertex(Vec3(0, 0, 1));
  std::vector<VertexId> ring;
  for (double deg : {0.0, 10.0, 65.0, 120.0})
    ring.push_back(m.add_vertex(Vec3(std::cos(deg * M_PI / 180), std::sin(deg * M_PI / 180), 0.5)));
  std::vector<TetId> fan;  // (a, b, ring[i], ring[i + 1]) turns anticlockwise about +z: positive
  for (int i = 0; i < 3; ++i) fan.push_back(m.add_tet(a, b, ring[i], ring[i + 1]));
  for (TetId t : fan) REQUIRE(m.volume(t) > 0);
  const TetId sharp = fan[0];
  const double before = tet_quality(m, sharp).min_dihedral;
  REQUIRE(before < 10.5);

  // Independently: the best a vertex inside the three tets can do, by sampling points and
  // joining each to the fan's boundary faces (the cavity's faces), in the measure the
  // insertion maximizes (q, quality/dihedral_objective.h: both angle targets).
  const AngleTargets targets;
  std::vector<std::array<Vec3, 3>> faces;
  for (const BoundaryFace& f : m.boundary_faces())
    faces.push_back({m.rest(f.vertices[0]), m.rest(f.vertices[2]), m.rest(f.vertices[1])});
  auto worst_q = [&](const Vec3& p) {
    double w = 1e300;
    for (const auto& f : faces) w = std::min(w, angle_q(f[0], f[1], f[2], p, targets));
    return w;
  };
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1), z(0, 1);
  double optimum = -1;
  for (int k = 0; k < 200000; ++k) optimum = std::max(optimum, worst_q(Vec3(u(rng), u(rng), z(rng))));
  const double q_before = angle_quality(m, sharp, targets).q;
  REQUIRE(optimum > 1.5 * q_before);

  // One insertion at the sharp tet, with and without the edges' stars.
  ImproveScope scope;
  scope.targets.radius_ratio_floor = 0.1;  // as once insertion starts (ImproveOptions::radius_ratio_floor)
  auto insert_once = [&](bool stars, TetMesh& out) {
    out = m;
    InsertionOptions io;
    io.edge_stars = stars;
    const auto r = improve_by_insertion(out, sharp, scope, io);
    double worst = 1e300;
    for (TetId t : out.tets()) worst = std::min(worst, angle_quality(out, t, targets).q);
    return r ? worst : q_before;
  };
  TetMesh without, with;
  const double q_without = insert_once(false, without), q_with = insert_once(true, with);
  CHECK(with.num_tets() == 8);           // the vertex joined to the fan's eight boundary faces
  CHECK(q_with >= 0.95 * optimum);       // the ascent finds about what sampling finds
  CHECK(q_with <= optimum * 1.02);       // and no more: the same cavity
  CHECK(q_with > q_without);             // grown from the sharp tet alone, less
  double min_with = 180;
  for (TetId t : with.tets()) min_with = std::min(min_with, tet_quality(with, t).min_dihedral);
  CHECK(min_with > before);
  CHECK(with.total_volume() == Approx(m.total_volume()).epsilon(1e-12));
}

TEST_CASE("improve: a vertex where a cut's front bends slides along the front, both sides with it", "[improve]") {
  // A crack along the lattice plane z = 0.5 of a unit box, opened where x < 0.5 or y < 0.5 (an
  // L reaching the box's sides; the vertices there duplicated for the tets above): its front
  // runs along x = 0.5 and y = 0.5 and bends by 90 degrees at (0.5, 0.5, 0.5). The two sides'
  // faces coincide and carry kTagCut.
  TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
  REQUIRE(testing::crack_where(m, 2, 0.5, [](const Vec3& p) { return p.x() < 0.4 || p.y() < 0.4; }) > 0);
  for (TetId t : m.tets())
    for (int f = 0; f < 4; ++f)
      if (!m.neighbor(t, f).is_valid()) {
        bool on_plane = true;
        for (VertexId w : m.face_vertices(t, f)) on_plane = on_plane && m.rest(w).z() == 0.5;
        m.set_face_tag(t, f, on_plane ? kTagCut : kTagSurface);
      }
  VertexId corner;
  for (VertexId v : m.vertices())
    if (m.rest(v) == Vec3(0.5, 0.5, 0.5)) corner = v;
  REQUIRE(corner.is_valid());
  // The corner pushed along the front towards (0.75, 0.5): the tets between it and its
  // neighbour there turn flat. Its front is now (0.75, 0.5) - (0.7, 0.5) - (0.5, 0.75).
  const Vec3 pushed(0.7, 0.5, 0.5), a(0.75, 0.5, 0.5), b(0.5, 0.75, 0.5);
  m.set_rest(corner, pushed);
  REQUIRE_NOTHROW(m.validate());
  m.discard_change();
  auto cut_area = [&](double& up, double& down) {
    up = down = 0;
    for (TetId t : m.tets())
      for (int f = 0; f < 4; ++f)
        if (!m.neighbor(t, f).is_valid() && m.face_tag(t, f) == kTagCut) {
          const auto fv = m.face_vertices(t, f);
          const Vec3 n = (m.rest(fv[1]) - m.rest(fv[0])).cross(m.rest(fv[2]) - m.rest(fv[0])) / 2;
          CHECK(std::abs(n.x()) + std::abs(n.y()) <= 1e-12);  // in the plane z = 0.5
          (n.z() > 0 ? up : down) += std::abs(n.z());
        }
  };
  double volume = 0, up0 = 0, down0 = 0;
  for (TetId t : m.tets()) volume += m.volume(t);
  cut_area(up0, down0);
  const QualityRange before = quality_range(m, 10.0);
  // Smoothing alone (flips would take the flat tets too), surface and cut kept exactly.
  ImproveOptions o;
  o.time_limit_s = 60;
  o.flips = false;
  o.collapse = false;
  const ImproveReport r = improve(m, o);
  REQUIRE_NOTHROW(m.validate());
  CHECK(std::count(r.moved_vertices.begin(), r.moved_vertices.end(), corner) > 0);
  const Vec3 p = m.rest(corner);
  CAPTURE(p.transpose());
  // On the old front: one of its two segments at the corner.
  auto on_segment = [&](const Vec3& s, const Vec3& e) {
    const double t = (p - s).dot(e - s) / (e - s).squaredNorm();
    return t >= -1e-12 && t <= 1 + 1e-12 && (s + t * (e - s) - p).norm() <= 1e-12;
  };
  CHECK((on_segment(pushed, a) || on_segment(pushed, b)));
  CHECK(p != pushed);
  CHECK(r.min_dihedral_after > before.min_dihedral + 5);
  // The body's volume exactly; the two sides still coincide (as much cut faces up as down,
  // each side triangulated on its own by the flips on it), and the opening changed by at most
  // the triangle between the corner's two front segments on each side.
  double volume_after = 0, up = 0, down = 0;
  for (TetId t : m.tets()) volume_after += m.volume(t);
  CHECK(std::abs(volume_after - volume) <= 1e-12 * volume);
  cut_area(up, down);
  CHECK(std::abs(up - down) <= 1e-12);
  const double corner_triangle = 0.5 * (a - pushed).cross(b - pushed).norm();
  CHECK(std::abs(up - up0) <= corner_triangle + 1e-12);
}
