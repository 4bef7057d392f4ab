// CGAL Mesh_3 on surfaces and images: invariants over CGAL's data set and our own shapes.
// Sizes are coarse: the whole area stays within a few minutes.
#include <catch2/catch.hpp>

#include <fstream>
#include <set>

#include "mesh/errors.h"
#include "mesh/io/surface.h"
#include "mesh/tetrahedralize/pipeline.h"
#include "tests/tetra/shapes.h"

using namespace incise;
using namespace incise::testing;

namespace {

const std::string kData = INCISE_CGAL_DATA_DIR;

bool same_mesh(const TetMesh& a, const TetMesh& b) {
  if (a.num_vertices() != b.num_vertices() || a.num_tets() != b.num_tets()) return false;
  for (VertexId v : a.vertices())
    if (a.rest(v) != b.rest(v)) return false;
  for (TetId t : a.tets())
    if (a.tet_vertices(t) != b.tet_vertices(t) || a.label(t) != b.label(t)) return false;
  return true;
}

double diag(const SurfaceMesh& s) {
  Eigen::AlignedBox3d box;
  for (const Vec3& p : s.vertices) box.extend(p);
  return box.diagonal().norm();
}

TetraOptions coarse(double fraction) {
  TetraOptions o;
  o.size = Length{fraction, true};
  return o;
}

}  // namespace

TEST_CASE("Mesh_3 on our own closed shapes, at extreme scales", "[tetra][cgal]") {
  for (double scale : {1e-6, 1.0, 1e6}) {
    INFO("scale " << scale);
    TetraStats st;
    SECTION("box") {
      TetraOptions o = coarse(0.08);
      o.features_angle = 60;  // 12 triangles: too few for the auto mode to call it a CAD part
      const TetMesh m = tetrahedralize_surface(box_surface(Vec3(1, 2, 3) * scale), o, &st);
      check_output(m, 6 * std::pow(scale, 3), 1e-6);  // sharp features keep the box exact
      CHECK(st.min_dihedral > 10);
    }
    SECTION("torus") {
      const SurfaceMesh s = torus_surface(2 * scale, 0.7 * scale, 48, 24);
      // The tube is 0.2 of the diagonal thick: 3% gives a few tets across it.
      const TetMesh m = tetrahedralize_surface(s, coarse(0.03), &st);
      check_output(m, enclosed_volume(s), 0.03);
      CHECK(st.min_dihedral > 10);
      CHECK(st.max_dihedral < 170);
    }
  }
}

TEST_CASE("Mesh_3 on CGAL meshes: sphere, elephant, fandisk", "[tetra][cgal]") {
  for (const char* name : {"sphere.off", "elephant.off", "fandisk.off"}) {
    INFO(name);
    const SurfaceMesh s = read_surface(kData + "/meshes/" + name);
    PipelineOptions po;
    po.tetra = coarse(0.04);
    PipelineReport rep;
    const TetMesh m = mesh_surface(s, po, &rep);
    check_output(m, std::abs(enclosed_volume(s)), 0.06);  // coarse: facets cut the convex parts
    // Smooth input gets no protected features and the 15-degree sliver target reaches
    // about 12-15 degrees; protected creases (fandisk) leave worse tets next to them.
    CHECK(rep.stats.min_dihedral > (rep.stats.features_angle > 0 ? 5 : 10));
    CHECK(rep.stats.max_dihedral < 170);
    std::set<int> labels;
    for (TetId t : m.tets()) labels.insert(m.label(t));
    CHECK(labels == std::set<int>{1});
  }
}

TEST_CASE("Mesh_3 keeps the sharp features of fandisk", "[tetra][cgal]") {
  const SurfaceMesh s = read_surface(kData + "/meshes/fandisk.off");
  TetraOptions o = coarse(0.05);
  const TetMesh with = tetrahedralize_surface(s, o);
  o.features_angle = 0;
  const TetMesh without = tetrahedralize_surface(s, o);
  // The boundary of the feature-protected mesh follows the input closer (the corners and
  // creases are vertices and edges of the mesh, not cut off).
  const SurfaceDistance dw = surface_distance(boundary_surface(with), s);
  const SurfaceDistance dn = surface_distance(boundary_surface(without), s);
  CHECK(dw.max < dn.max);
  CHECK(dw.max < 0.01 * diag(s));
}

TEST_CASE("Mesh_3 is repeatable with the same seed", "[tetra][cgal]") {
  const SurfaceMesh s = read_surface(kData + "/meshes/sphere.off");
  TetraOptions o = coarse(0.06);
  o.seed = 7;
  const TetMesh a = tetrahedralize_surface(s, o);
  const TetMesh b = tetrahedralize_surface(s, o);
  CHECK(same_mesh(a, b));
  o.optimize = kOptimizeOdt | kOptimizePerturb | kOptimizeExude;
  const TetMesh c = tetrahedralize_surface(s, o);
  const TetMesh d = tetrahedralize_surface(s, o);
  CHECK(same_mesh(c, d));
}

TEST_CASE("Mesh_3 on the labeled liver image keeps its labels", "[tetra][cgal]") {
  PipelineOptions po;
  po.tetra = coarse(0.05);
  PipelineReport rep;
  const TetMesh m = mesh_file(kData + "/images/liver.inr.gz", po, &rep);
  check_output(m, rep.stats.input_volume, 0.05);
  std::set<int> labels;
  for (TetId t : m.tets()) labels.insert(m.label(t));
  CHECK(labels.size() >= 2);
  CHECK(labels.count(84) == 0);  // the 2-voxel label is dropped as noise
  CHECK(labels.count(0) == 0);
  CHECK(rep.stats.min_dihedral > 5);
}

TEST_CASE("Bad input gets a clear error", "[tetra]") {
  PipelineOptions po;
  SECTION("empty file") {
    const std::string path = std::string(INCISE_BINARY_DIR) + "/tetra_empty.off";
    std::ofstream(path).close();
    CHECK_THROWS_AS(mesh_file(path, po), Error);
  }
  SECTION("missing file") { CHECK_THROWS_AS(mesh_file("/nonexistent/x.stl", po), IoError); }
  SECTION("empty surface") { CHECK_THROWS_AS(mesh_surface(SurfaceMesh{}, po), InvalidArgument); }
  SECTION("a single triangle") {
    SurfaceMesh s;
    s.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    s.triangles = {{0, 1, 2}};
    CHECK_THROWS_WITH(mesh_surface(s, po), Catch::Contains("encloses no volume"));
  }
  SECTION("a size larger than the model") {
    po.tetra.size = Length{5.0, false};
    CHECK_THROWS_WITH(mesh_surface(box_surface(Vec3(1, 1, 1)), po), Catch::Contains("larger than the model"));
  }
  SECTION("a size needing billions of tets is refused with an estimate") {
    po.tetra.size = Length{1e-4, false};
    CHECK_THROWS_WITH(mesh_surface(box_surface(Vec3(1, 1, 1)), po), Catch::Contains("would need about"));
    po.engine = TetraEngine::Stuffing;
    CHECK_THROWS_AS(mesh_surface(box_surface(Vec3(1, 1, 1)), po), InvalidArgument);
  }
  SECTION("an open surface without --repair suggests --repair") {
    SurfaceMesh s = sphere_surface(1, 2);
    s.triangles.pop_back();
    CHECK_THROWS_WITH(mesh_surface(s, po), Catch::Contains("--repair"));
  }
  SECTION("an unknown label size") {
    po.tetra.label_sizes[12345] = 1.0;
    CHECK_THROWS_AS(mesh_file(kData + "/images/liver.inr.gz", po), InvalidArgument);
  }
}
