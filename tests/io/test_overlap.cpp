// Overlapping tets (mesh/overlap.h): found wherever two tets share volume, whether they share
// an edge, a vertex or nothing, and never for tets that only touch (face neighbours, the two
// sides of a cut, a T-junction, degenerate tets); the readers refuse such meshes naming the
// later tet's line, except deformed frames.
#include <cmath>
#include <random>

#include "cut/cutter.h"
#include "io_test_util.h"
#include "mesh/errors.h"
#include "mesh/overlap.h"

using namespace incise;
using namespace incise::testing;

namespace {

VertexId corner_near(const TetMesh& m, const Vec3& p) {
  VertexId best;
  double d = INFINITY;
  for (VertexId v : m.vertices())
    if ((m.rest(v) - p).norm() < d) d = (m.rest(v) - p).norm(), best = v;
  return best;
}

// Appends the tets (and vertices) of `b` to `a`, moved by `shift`.
void append(TetMesh& a, const TetMesh& b, const Vec3& shift) {
  std::vector<VertexId> map(b.vertex_capacity());
  for (VertexId v : b.vertices()) map[v.idx()] = a.add_vertex(b.rest(v) + shift);
  for (TetId t : b.tets()) {
    const auto& tv = b.tet_vertices(t);
    a.add_tet(map[tv[0].idx()], map[tv[1].idx()], map[tv[2].idx()], map[tv[3].idx()]);
  }
}

TetMesh one_tet(const std::array<Vec3, 4>& p) {
  TetMesh m;
  for (const Vec3& x : p) m.add_vertex(x);
  m.add_tet(VertexId(0), VertexId(1), VertexId(2), VertexId(3));
  return m;
}

}  // namespace

TEST_CASE("overlap: valid meshes have none, also where tets only touch", "[io][overlap]") {
  CHECK_FALSE(find_overlapping_tets(make_box(Vec3(4, 2, 1), {16, 8, 4})));
  CHECK_FALSE(find_overlapping_tets(make_box(Vec3(1, 1, 1), {5, 5, 5}, 1, BoxSplit::Mirrored)));
  CHECK_FALSE(find_overlapping_tets(labeled_ellipsoid()));
  // Two boxes side by side of different resolution: their faces meet in T-junctions.
  TetMesh pair = make_box(Vec3(1, 1, 1), {4, 4, 4});
  append(pair, make_box(Vec3(1, 1, 1), {3, 5, 2}), Vec3(1, 0, 0));
  CHECK_FALSE(find_overlapping_tets(pair));
  // A cut: both sides lie where the uncut tets were, touching along the cut faces.
  TetMesh cut = make_box(Vec3(2, 1, 1), {8, 4, 4});
  Cutter cutter(cut);
  cutter.cut_plane(Vec3(1.03, 0.5, 0.5), Vec3(1, 0.2, 0.1).normalized());
  REQUIRE(cut.num_tets() > 8 * 4 * 4 * 6);
  CHECK_FALSE(find_overlapping_tets(cut));
  // A flat tet inside the box has no volume to share.
  TetMesh flat = make_box(Vec3(1, 1, 1), {2, 2, 2});
  append(flat, one_tet({Vec3(0.1, 0.1, 0.5), Vec3(0.9, 0.1, 0.5), Vec3(0.1, 0.9, 0.5), Vec3(0.9, 0.9, 0.5)}), Vec3::Zero());
  CHECK_FALSE(find_overlapping_tets(flat));
}

TEST_CASE("overlap: found whether the tets share an edge, a vertex or nothing", "[io][overlap]") {
  const Vec3 o(0, 0, 0), x(1, 0, 0), y(0, 1, 0), z(0, 0, 1);
  SECTION("a tet spanning a generated box (shares its corners, no face)") {
    TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
    const auto before = m.num_tets();
    m.add_tet(corner_near(m, o), corner_near(m, x), corner_near(m, y), corner_near(m, z));
    auto hit = find_overlapping_tets(m);
    REQUIRE(hit);
    CHECK(hit->first.idx() < hit->second.idx());
    CHECK(hit->second.idx() == before);  // the spanning tet is the later one
  }
  SECTION("two copies of a part, half a cell apart (no shared vertex)") {
    TetMesh m = make_box(Vec3(1, 1, 1), {3, 3, 3});
    append(m, make_box(Vec3(1, 1, 1), {3, 3, 3}), Vec3(0.17, 0.05, 0.02));
    CHECK(find_overlapping_tets(m));
  }
  SECTION("a small part wholly inside a big tet") {
    TetMesh m = one_tet({o, 10 * x, 10 * y, 10 * z});
    append(m, make_box(Vec3(0.5, 0.5, 0.5), {1, 1, 1}), Vec3(1, 1, 1));
    CHECK(find_overlapping_tets(m));
  }
  SECTION("two tets on one edge, the second turned into the first") {
    TetMesh m;
    for (const Vec3& p : {o, z, x, y, Vec3(1, 0.3, 0), Vec3(0.3, 1, 0)}) m.add_vertex(p);
    m.add_tet(VertexId(0), VertexId(1), VertexId(2), VertexId(3));
    m.add_tet(VertexId(0), VertexId(1), VertexId(4), VertexId(5));
    CHECK(find_overlapping_tets(m));
  }
  SECTION("two tets on one vertex, overlapping near it") {
    TetMesh m;
    for (const Vec3& p : {o, x, y, z, Vec3(0.2, 0.2, 1), Vec3(1, 0.3, 0.3), Vec3(0.3, 1, 0.2)}) m.add_vertex(p);
    m.add_tet(VertexId(0), VertexId(1), VertexId(2), VertexId(3));
    m.add_tet(VertexId(0), VertexId(4), VertexId(5), VertexId(6));
    CHECK(find_overlapping_tets(m));
  }
  SECTION("the same pair touching at the vertex only") {
    TetMesh m;
    for (const Vec3& p : {o, x, y, z, Vec3(-1, -0.1, -0.2), Vec3(-0.2, -1, -0.1), Vec3(-0.1, -0.2, -1)}) m.add_vertex(p);
    m.add_tet(VertexId(0), VertexId(1), VertexId(2), VertexId(3));
    m.add_tet(VertexId(0), VertexId(4), VertexId(5), VertexId(6));
    CHECK_FALSE(find_overlapping_tets(m));
  }
}

TEST_CASE("overlap: random boxes moved into each other by a random shift", "[io][overlap]") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.4, 0.4);
  for (int trial = 0; trial < 20; ++trial) {
    TetMesh m = make_box(Vec3(1, 1, 1), {2, 2, 2});
    const Vec3 shift(u(rng), u(rng), u(rng));
    append(m, make_box(Vec3(1, 1, 1), {2, 2, 2}), shift);
    CHECK(find_overlapping_tets(m).has_value());  // |shift| < 1 on every axis: the boxes overlap
    TetMesh apart = make_box(Vec3(1, 1, 1), {2, 2, 2});
    append(apart, make_box(Vec3(1, 1, 1), {2, 2, 2}), shift + Vec3(1.0, 0, 0) * (shift.x() >= 0 ? 1 : -1));
    CHECK_FALSE(find_overlapping_tets(apart).has_value());  // moved apart by the box's width
  }
}

TEST_CASE("overlap: the readers refuse overlapping tets, naming the later tet's line", "[io][overlap]") {
  ScratchDir dir("overlap");
  TetMesh m = make_box(Vec3(1, 1, 1), {2, 2, 2});
  m.add_tet(corner_near(m, Vec3(0, 0, 0)), corner_near(m, Vec3(1, 0, 0)), corner_near(m, Vec3(0, 1, 0)),
            corner_near(m, Vec3(0, 0, 1)));
  const std::size_t n = m.num_tets();
  for (const char* name : {"s.mesh", "s.msh", "s.vtk", "s.vtu", "s.node"}) {
    INFO(name);
    write_tet_mesh(m, dir / name);
    try {
      read_tet_mesh(dir / name);
      FAIL("read");
    } catch (const IoError& e) {
      const std::string what = e.what();
      CHECK(what.find("overlaps tet #") != std::string::npos);
      CHECK(what.find("their interiors intersect") != std::string::npos);
      // The line is named where the format has one per tet; VTU (XML) names the tet's number.
      if (std::string(name) == "s.vtu") CHECK(what.find("tet #" + std::to_string(n - 1) + " overlaps") != std::string::npos);
      else CHECK(what.find(":0:") == std::string::npos);
    }
    ReadOptions lax;
    lax.refuse_overlaps = false;
    CHECK(read_tet_mesh(dir / name, lax).num_tets() == n);
  }
  // A frame (deformed positions with their displacement) may press a cut's sides together.
  MeshFields fields;
  fields.point_data.push_back(Field{"displacement", 3, std::vector<double>(3 * m.vertex_capacity(), 0.0)});
  for (const char* name : {"f.vtu", "f.vtk"}) {
    write_tet_mesh_with_fields(m, dir / name, fields);
    CHECK(read_tet_mesh(dir / name).num_tets() == n);
  }
}

TEST_CASE("a deformed frame with inverted tets reads back, the same shape as a rest mesh does not",
          "[io][overlap]") {
  // Issue 39 item 1: frames incise wrote with tets the motion inverted were refused by
  // `incise info`, incise.read and `incise view RUN` ("tet #N overlaps tet #M").
  ScratchDir dir("inverted_frame");
  const TetMesh m = make_box(Vec3(1, 1, 1), {2, 2, 2});
  std::vector<Vec3> pos(m.vertex_capacity());
  std::vector<double> disp(3 * m.vertex_capacity(), 0.0);
  for (VertexId v : m.vertices()) pos[v.idx()] = m.rest(v);
  const VertexId centre = corner_near(m, Vec3(0.5, 0.5, 0.5));
  pos[centre.idx()] = Vec3(0.5, 0.5, 1.4);  // pushed out through the top: the tets above invert
  disp[3 * centre.idx() + 2] = 0.9;
  MeshFields frame;
  frame.points = &pos;
  frame.point_data.push_back(Field{"displacement", 3, disp});
  for (const char* name : {"f.vtu", "f.vtk"}) {
    INFO(name);
    write_tet_mesh_with_fields(m, dir / name, frame);
    ReadReport report;
    const TetMesh back = read_tet_mesh(dir / name, &report);
    CHECK(back.num_tets() == m.num_tets());
    CHECK(report.reoriented_tets > 0);
    CHECK(back.rest(centre).isApprox(Vec3(0.5, 0.5, 1.4)));  // the deformed shape, as written
  }
  MeshFields rest_like;
  rest_like.points = &pos;
  write_tet_mesh_with_fields(m, dir / "r.vtu", rest_like);
  CHECK_THROWS_WITH(read_tet_mesh(dir / "r.vtu"), Catch::Contains("overlaps tet #"));
}
