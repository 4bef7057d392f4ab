// The improvement's operations that move the surface within the volume allowance: boundary
// flips between faces that are not coplanar (a cap triangle's long edge), slides along bent
// feature lines, and the staged growth of insertion. Checked against answers computed here
// from the coordinates: the flipped tets' angles, the volume the flip moves, the old polyline.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <set>

#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "quality/improve.h"
#include "testing/mesh_edits.h"

using namespace incise;

namespace {

double signed_volume(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  return (b - a).cross(c - a).dot(d - a) / 6;
}

// Smallest dihedral angle of a tet, in degrees, from the face normals (not quality/metrics).
double min_dihedral(const std::array<Vec3, 4>& x) {
  double lo = 180;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) {
      std::array<int, 2> kl{};  // the two other corners
      int n = 0;
      for (int m = 0; m < 4; ++m)
        if (m != i && m != j) kl[n++] = m;
      const Vec3 e = (x[j] - x[i]).normalized();
      Vec3 u = x[kl[0]] - x[i], v = x[kl[1]] - x[i];
      u -= e * e.dot(u);
      v -= e * e.dot(v);
      lo = std::min(lo, std::acos(std::clamp(u.normalized().dot(v.normalized()), -1.0, 1.0)) * 180 / M_PI);
    }
  return lo;
}

TetId add_positive(TetMesh& m, VertexId a, VertexId b, VertexId c, VertexId d) {
  if (signed_volume(m.rest(a), m.rest(b), m.rest(c), m.rest(d)) < 0) std::swap(c, d);
  return m.add_tet(a, b, c, d, 1);
}

double total_volume(const TetMesh& m) {
  double v = 0;
  for (TetId t : m.tets()) v += m.volume(t);
  return v;
}

// Distance from p to segment [a, b].
double to_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 e = b - a;
  const double s = std::clamp((p - a).dot(e) / e.squaredNorm(), 0.0, 1.0);
  return (a + s * e - p).norm();
}

}  // namespace

TEST_CASE("surface reshape: a cap triangle's long edge is flipped, the angle and volume as computed here",
          "[improve][reshape]") {
  // Two tets on the edge a-b; the boundary triangle (a, b, c0) is a cap (c0 0.054 from a-b), so
  // the tet (a, b, c0, p) has a tiny dihedral angle whatever its apex. Removing the edge a-b
  // (its two boundary faces become (a, c0, cm), (b, cm, c0)) leaves the tets (c0, cm, p, a) and
  // (c0, cm, p, b), and moves the surface by the tet (a, b, c0, cm).
  const Vec3 a(0, 0, 0), b(2, 0, 0), c0(1, 0.05, 0.02), cm(1, -1, 0), p(1, -0.3, -1);
  auto build = [&] {
    TetMesh m;
    const VertexId va = m.add_vertex(a), vb = m.add_vertex(b), v0 = m.add_vertex(c0), vm = m.add_vertex(cm),
                   vp = m.add_vertex(p);
    add_positive(m, va, vb, v0, vp);
    add_positive(m, va, vb, vm, vp);
    m.discard_change();
    return m;
  };
  const double before = std::min(min_dihedral({a, b, c0, p}), min_dihedral({a, b, cm, p}));
  const double expected = std::min(min_dihedral({c0, cm, p, a}), min_dihedral({c0, cm, p, b}));
  const double v0 = std::abs(signed_volume(a, b, c0, p)) + std::abs(signed_volume(a, b, cm, p));
  const double moved = std::abs(signed_volume(a, b, c0, cm));
  REQUIRE(expected > before + 10);

  ImproveOptions o;
  o.slide_curved = true;
  o.volume_tolerance = 2 * moved / v0;  // room for this flip, not for two
  o.time_limit_s = 60;
  TetMesh m = build();
  const ImproveReport r = improve(m, o);
  REQUIRE_NOTHROW(m.validate());
  CHECK(r.surface_flips == 1);
  CHECK(r.min_dihedral_before == Approx(before).margin(1e-9));
  CHECK(r.min_dihedral_after == Approx(expected).margin(1e-9));
  CHECK(m.num_tets() == 2);
  // The volume changes by exactly that tet (here a valley: the new faces lie outside).
  CHECK(std::abs(total_volume(m) - v0) == Approx(moved).epsilon(1e-9));
  CHECK(r.label_volume_change == Approx(moved / v0).epsilon(1e-9));

  // Within an allowance too small for it, or with reshaping off, the surface stays as it is.
  for (int k = 0; k < 2; ++k) {
    ImproveOptions strict = o;
    strict.volume_tolerance = k == 0 ? 0.5 * moved / v0 : 1;
    strict.reshape_surface = k == 0;
    TetMesh s = build();
    const ImproveReport rs = improve(s, strict);
    CHECK(rs.surface_flips == 0);
    CHECK(rs.min_dihedral_after == Approx(before).margin(1e-9));
    CHECK(total_volume(s) == Approx(v0).epsilon(1e-12));
  }
}

TEST_CASE("surface reshape: vertices on a bent feature line slide along the old line", "[improve][reshape]") {
  // A quarter tube: the rims where the outer wall (its own tag) meets the end caps are arcs, a
  // polyline bent by 11.25 degrees at each vertex. Each rim vertex but the corners is pushed
  // along its chord towards the next, so the input's polyline has work for the smoothing; every
  // vertex on a rim after the pass (moved, or inserted on a rim edge) must lie on the input's
  // polyline, and the label's volume within the allowance.
  TetMesh m = make_tube(0.5, 1.0, 0.25, 90, {2, 8, 2});
  const double kOuter = 1.0;
  auto on_rim = [&](const Vec3& x) {
    return std::abs(std::hypot(x.x(), x.y()) - kOuter) < 1e-9 && (std::abs(x.z()) < 1e-12 || std::abs(x.z() - 0.25) < 1e-12);
  };
  // Rim vertices per end, by polar angle.
  std::map<int, std::vector<VertexId>> rims;
  for (VertexId v : m.vertices())
    if (on_rim(m.rest(v))) rims[m.rest(v).z() > 0.1].push_back(v);
  REQUIRE(rims.size() == 2);
  for (auto& [end, vs] : rims) {
    REQUIRE(vs.size() == 9);
    std::sort(vs.begin(), vs.end(), [&](VertexId x, VertexId y) {
      return std::atan2(m.rest(x).y(), m.rest(x).x()) < std::atan2(m.rest(y).y(), m.rest(y).x());
    });
    for (std::size_t i = 1; i + 1 < vs.size(); i += 2)  // every other one, so each chord keeps an end
      m.set_rest(vs[i], m.rest(vs[i]) + 0.35 * (m.rest(vs[i + 1]) - m.rest(vs[i])));
  }
  testing::jitter(m, 0.2, 5);
  REQUIRE_NOTHROW(m.validate());
  m.discard_change();
  std::vector<std::pair<Vec3, Vec3>> segments;
  for (const auto& [end, vs] : rims)
    for (std::size_t i = 0; i + 1 < vs.size(); ++i) segments.push_back({m.rest(vs[i]), m.rest(vs[i + 1])});
  const double v0 = total_volume(m);
  std::set<std::uint32_t> rim_before;
  for (const auto& [end, vs] : rims)
    for (VertexId v : vs) rim_before.insert(v.idx());

  ImproveOptions o;
  o.slide_curved = true;
  o.volume_tolerance = 1e-2;
  o.insertion = GENERATE(false, true);
  o.time_limit_s = 60;
  const ImproveReport r = improve(m, o);
  REQUIRE_NOTHROW(m.validate());
  CHECK(r.feature_slides > 0);
  // The rim after the pass: vertices of faces of both tags (outer wall and cap).
  std::map<std::uint32_t, std::set<std::uint16_t>> tags_at;
  for (const auto& f : m.boundary_faces())
    for (VertexId v : f.vertices) tags_at[v.idx()].insert(f.tag);
  int on_line = 0, rim_moved = 0;
  double worst = 0;
  for (const auto& [v, tags] : tags_at) {
    if (!tags.count(kTagTubeOuter) || !tags.count(kTagSurface)) continue;
    const Vec3 x = m.rest(VertexId(v));
    if (std::abs(x.z()) > 1e-9 && std::abs(x.z() - 0.25) > 1e-9) continue;  // the sector's straight sides
    double d = 1e300;
    for (const auto& [s0, s1] : segments) d = std::min(d, to_segment(x, s0, s1));
    worst = std::max(worst, d);
    ++on_line;
    rim_moved += rim_before.count(v) > 0 && r.moved_vertices.end() != std::find(r.moved_vertices.begin(), r.moved_vertices.end(), VertexId(v));
  }
  UNSCOPED_INFO("rim vertices " << on_line << ", moved " << rim_moved << ", farthest from the old line " << worst);
  CHECK(on_line >= 18);
  CHECK(rim_moved > 0);
  CHECK(worst <= 1e-12);
  CHECK(std::abs(total_volume(m) - v0) <= o.volume_tolerance * v0 * (1 + 1e-9));
  CHECK(r.label_volume_change <= o.volume_tolerance * (1 + 1e-9));
}

TEST_CASE("surface reshape: curved meshes keep each label's volume within the tolerance", "[improve][reshape]") {
  // An ellipsoid of two labels, jittered inside: curved slides, feature-line slides, surface
  // flips and insertion all spend one allowance per label.
  TetMesh m = make_ellipsoid(Vec3(1.0, 0.7, 0.5), 3);
  for (TetId t : m.tets()) {
    Vec3 c = Vec3::Zero();
    for (VertexId v : m.tet_vertices(t)) c += m.rest(v) / 4;
    if (c.x() < 0) m.set_label(t, 2);
  }
  testing::jitter(m, 0.3, 11);
  m.discard_change();
  std::map<int, double> before;
  for (TetId t : m.tets()) before[m.label(t)] += m.volume(t);
  ImproveOptions o;
  o.slide_curved = true;
  o.insertion = GENERATE(false, true);
  o.time_limit_s = 60;
  const ImproveReport r = improve(m, o);
  REQUIRE_NOTHROW(m.validate());
  std::map<int, double> after;
  for (TetId t : m.tets()) after[m.label(t)] += m.volume(t);
  double largest = 0;
  for (const auto& [label, v] : before) largest = std::max(largest, std::abs(after.at(label) - v) / v);
  UNSCOPED_INFO("surface flips " << r.surface_flips << ", feature slides " << r.feature_slides << ", volume moved "
                                 << largest << ", dihedral " << r.min_dihedral_before << " -> " << r.min_dihedral_after);
  CHECK(r.surface_flips + r.feature_slides + r.smoothing_moves > 0);
  CHECK(largest <= o.volume_tolerance * (1 + 1e-6));
  CHECK(r.label_volume_change == Approx(largest).margin(1e-15));
  CHECK(r.min_dihedral_after >= r.min_dihedral_before);
}

TEST_CASE("growth policy: the report says when the cap stopped insertion", "[improve][insertion]") {
  // The sample elephant needs about 1.2x its tets to reach its best with insertion: a cap of
  // 1 allows only what the default pass's 3-2 flips freed, 1.05 a little more, 3 all it asks for.
  const TetMesh input = read_tet_mesh(INCISE_SOURCE_DIR "/samples/elephant.msh");
  ImproveOptions o;
  o.insertion = true;
  o.time_limit_s = 60;
  std::map<double, ImproveReport> runs;
  for (double cap : {1.0, 1.05, 3.0}) {
    TetMesh m = input;
    m.discard_change();
    o.max_growth = cap;
    runs[cap] = improve(m, o);
    CHECK(double(m.num_tets()) <= cap * double(input.num_tets()));
  }
  CHECK(runs[1.0].growth_capped);
  CHECK(runs[1.05].insertions > runs[1.0].insertions);
  CHECK(runs[1.05].growth_capped);
  CHECK_FALSE(runs[3.0].growth_capped);
  // Insertion starts from the converged default pass: never worse than none at all.
  CHECK(runs[1.05].min_dihedral_after >= runs[1.0].min_dihedral_after);
  CHECK(runs[3.0].min_dihedral_after >= runs[1.0].min_dihedral_after);
}
