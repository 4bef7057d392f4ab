// Uniform 1:8 refinement and point location: the refined mesh is valid and conforming, keeps
// volume, labels and boundary tags; located points reproduce an affine field exactly (the
// interpolation incise trade compares meshes with), and points off the mesh clamp onto it.
#include <catch2/catch.hpp>

#include <map>
#include <random>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "mesh/point_locator.h"
#include "mesh/refine.h"

using namespace incise;

namespace {

double volume(const TetMesh& m) {
  double v = 0;
  for (TetId t : m.tets()) v += m.volume(t);
  return v;
}

double tagged_area(const TetMesh& m, std::uint16_t tag) {
  double a = 0;
  for (const BoundaryFace& f : m.boundary_faces())
    if (f.tag == tag)
      a += 0.5 * (m.rest(f.vertices[1]) - m.rest(f.vertices[0])).cross(m.rest(f.vertices[2]) - m.rest(f.vertices[0])).norm();
  return a;
}

double longest_edge(const TetMesh& m) {
  double l = 0;
  for (TetId t : m.tets()) {
    const auto v = m.tet_vertices(t);
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) l = std::max(l, (m.rest(v[std::size_t(i)]) - m.rest(v[std::size_t(j)])).norm());
  }
  return l;
}

}  // namespace

TEST_CASE("refine_uniform: 8 children per tet, conforming, volume, labels and tags kept", "[mesh][refine]") {
  const TetMesh tube = make_tube(1, 2, 0.5, 90, {2, 6, 1});
  const TetMesh liver = read_tet_mesh(std::string(INCISE_SOURCE_DIR) + "/samples/liver.msh");
  for (const TetMesh* in : {&tube, &liver}) {
    const TetMesh out = refine_uniform(*in);
    CHECK(out.num_tets() == 8 * in->num_tets());
    CHECK_NOTHROW(out.validate());  // conforming: every interior face has one tet on each side
    CHECK(volume(out) == Approx(volume(*in)).epsilon(1e-12));
    CHECK(out.boundary_faces().size() == 4 * in->boundary_faces().size());
    CHECK(longest_edge(out) <= 0.5 * longest_edge(*in) * (1 + 1e-12) * 1.8);  // octahedron diagonals are interior
    for (std::uint16_t tag : {std::uint16_t(kTagSurface), std::uint16_t(kTagTubeInner), std::uint16_t(kTagTubeOuter)})
      CHECK(tagged_area(out, tag) == Approx(tagged_area(*in, tag)).epsilon(1e-12).margin(1e-15));
    std::map<int, double> vin, vout;
    for (TetId t : in->tets()) vin[in->label(t)] += in->volume(t);
    for (TetId t : out.tets()) vout[out.label(t)] += out.volume(t);
    REQUIRE(vin.size() == vout.size());
    for (const auto& [label, v] : vin) CHECK(vout[label] == Approx(v).epsilon(1e-12));
    // The input's vertices keep their ids and places.
    for (VertexId v : in->vertices()) CHECK(out.rest(v) == in->rest(v));
  }
  TetMesh holes = make_box(Vec3(1, 1, 1), {1, 1, 1});
  holes.remove_tet(*holes.tets().begin());
  CHECK_THROWS_AS(refine_uniform(holes), InvalidArgument);
}

TEST_CASE("point location reproduces an affine field exactly and clamps points off the mesh", "[mesh][refine]") {
  const TetMesh coarse = read_tet_mesh(std::string(INCISE_SOURCE_DIR) + "/samples/liver.msh");
  const TetMesh fine = refine_uniform(coarse);
  const Eigen::Matrix3d a = (Eigen::Matrix3d() << 0.3, -1.2, 0.5, 2.0, 0.1, -0.7, 0.4, 0.9, 1.1).finished();
  const Vec3 b(0.2, -3, 7);
  std::vector<double> field(3 * fine.vertex_capacity());
  for (VertexId v : fine.vertices()) {
    Eigen::Map<Vec3> f(&field[3 * v.idx()]);
    f = a * fine.rest(v) + b;
  }
  const PointLocator loc(fine);
  double worst = 0, scale = 0;
  auto check = [&](const Vec3& p) {
    const PointLocation at = loc.locate(p);
    REQUIRE(at.tet.is_valid());
    CHECK(at.distance == 0);
    Vec3 got;
    PointLocator::interpolate(fine, at, field.data(), 3, got.data());
    worst = std::max(worst, (got - (a * p + b)).norm());
    scale = std::max(scale, (a * p + b).norm());
  };
  // Every coarse vertex (the meshes share the surface) and random points inside coarse tets.
  for (VertexId v : coarse.vertices()) check(coarse.rest(v));
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  int n = 0;
  for (TetId t : coarse.tets()) {
    if (++n % 7) continue;
    double w[4], s = 0;
    for (double& x : w) s += (x = u(rng));
    Vec3 p = Vec3::Zero();
    for (int l = 0; l < 4; ++l) p += w[l] / s * coarse.rest(coarse.tet_vertices(t)[std::size_t(l)]);
    check(p);
  }
  CHECK(worst <= 1e-12 * scale);
  // A point outside: clamped onto the nearest tet found, with its distance.
  Vec3 lo = Vec3::Constant(1e300);
  for (VertexId v : fine.vertices()) lo = lo.cwiseMin(fine.rest(v));
  const PointLocation off = loc.locate(lo - Vec3(1, 1, 1));
  REQUIRE(off.tet.is_valid());
  CHECK(off.distance > std::sqrt(3.0) * 0.999);
  for (double w : off.weights) CHECK(w >= 0);
  // The box: a point just past a face lands on that face.
  const TetMesh box = make_box(Vec3(1, 1, 1), {3, 3, 3});
  const PointLocator bl(box);
  const PointLocation face = bl.locate(Vec3(0.5, 0.5, 1.25));
  CHECK(face.distance == Approx(0.25));
}
