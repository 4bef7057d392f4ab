// Level-set repair of dirty surfaces and the stuffing engine.
#include <catch2/catch.hpp>

#include <set>

#include "mesh/errors.h"
#include "mesh/io/surface.h"
#include "mesh/isosurface_stuffing.h"
#include "mesh/tetrahedralize/pipeline.h"
#include "tests/tetra/shapes.h"

using namespace incise;
using namespace incise::testing;

namespace {

const std::string kRepairData = INCISE_CGAL_DATA_DIR;

double union_of_spheres(double r, double d) {
  const double lens = M_PI * (4 * r + d) * (2 * r - d) * (2 * r - d) / 12;
  return 2 * 4.0 / 3 * M_PI * r * r * r - lens;
}

}  // namespace

TEST_CASE("Stuffing engine: guaranteed dihedral bounds, volume, labels", "[tetra]") {
  PipelineOptions po;
  po.engine = TetraEngine::Stuffing;
  po.tetra.size = Length{0.025, true};
  for (double scale : {1e-5, 1.0, 1e5}) {
    INFO("scale " << scale);
    const SurfaceMesh shapes[] = {sphere_surface(scale, 4), torus_surface(2 * scale, 0.7 * scale, 96, 48)};
    for (const SurfaceMesh& s : shapes) {
      PipelineReport rep;
      const TetMesh m = mesh_surface(s, po, &rep);
      check_output(m, enclosed_volume(s), 0.03);
      CHECK(rep.stats.min_dihedral >= kStuffingMinDihedral - 1e-6);
      CHECK(rep.stats.max_dihedral <= kStuffingMaxDihedral + 1e-6);
      for (TetId t : m.tets()) REQUIRE(m.label(t) == 1);
      // Deterministic: the same input gives the same mesh.
      const TetMesh again = mesh_surface(s, po);
      CHECK(again.num_tets() == m.num_tets());
      CHECK(again.total_volume() == m.total_volume());
    }
  }
}

TEST_CASE("Graded stuffing from a level set: fewer tets, same surface, same bounds", "[tetra]") {
  PipelineOptions po;
  po.engine = TetraEngine::Stuffing;
  po.tetra.size = Length{0.01, true};
  const SurfaceMesh s = sphere_surface(1.0, 5);
  PipelineReport uniform_rep, graded_rep;
  const TetMesh uniform = mesh_surface(s, po, &uniform_rep);
  po.tetra.graded = true;
  const TetMesh graded = mesh_surface(s, po, &graded_rep);
  check_output(graded, enclosed_volume(s), 0.03);
  INFO("graded " << graded.num_tets() << " vs uniform " << uniform.num_tets() << " tets");
  CHECK(graded.num_tets() < 0.7 * uniform.num_tets());
  CHECK(graded.total_volume() == Approx(uniform.total_volume()).epsilon(0.01));
  CHECK(graded_rep.stats.min_dihedral >= kStuffingMinDihedral - 1e-6);
  CHECK(graded_rep.stats.max_dihedral <= kStuffingMaxDihedral + 1e-6);
}

TEST_CASE("Repair closes holes and meshes the closed shape", "[tetra][cgal]") {
  SurfaceMesh s = sphere_surface(1, 3);
  for (int k = 0; k < 6; ++k) s.triangles.erase(s.triangles.begin() + 37 * k);  // six holes
  PipelineOptions po;
  po.tetra.size = Length{0.05, true};
  CHECK_THROWS_WITH(mesh_surface(s, po), Catch::Contains("--repair"));
  po.repair = true;
  SECTION("patched") {}
  SECTION("closed by the level set") { po.level_set.closing_radius = 0.3; }
  for (TetraEngine e : {TetraEngine::Cgal, TetraEngine::Stuffing}) {
    po.engine = e;
    PipelineReport rep;
    const TetMesh m = mesh_surface(s, po, &rep);
    CHECK(rep.repaired);
    INFO(rep.stats.engine);
    CHECK(rep.repair.distance.max < rep.check.largest_hole_radius);  // only across the patches
    check_output(m, std::abs(enclosed_volume(s)), 0.05);
  }
}

TEST_CASE("Repair resolves self-intersecting shells to their union", "[tetra][cgal]") {
  const Vec3 c(0.7, 0.3, 0.1);
  const SurfaceMesh s = merged(sphere_surface(1, 4), sphere_surface(1, 4, c));
  PipelineOptions po;
  po.tetra.size = Length{0.04, true};
  CHECK_THROWS_WITH(mesh_surface(s, po), Catch::Contains("self-intersecting"));
  po.repair = true;
  PipelineReport rep;
  const TetMesh m = mesh_surface(s, po, &rep);
  check_output(m, union_of_spheres(1, c.norm()), 0.03);
  CHECK(rep.check.components == 2);
}

TEST_CASE("Repair of CGAL's elephant-with-holes", "[tetra][cgal]") {
  const SurfaceMesh holes = read_surface(kRepairData + "/meshes/elephant-with-holes.off");
  const SurfaceMesh closed = read_surface(kRepairData + "/meshes/elephant.off");
  PipelineOptions po;
  po.tetra.size = Length{0.04, true};
  CHECK_THROWS_WITH(mesh_surface(holes, po), Catch::Contains("--repair"));
  po.repair = true;
  PipelineReport rep;
  const TetMesh m = mesh_surface(holes, po, &rep);
  CHECK(rep.check.holes > 0);
  // The holes are filled: the volume is the closed elephant's, within the coarse size.
  check_output(m, std::abs(enclosed_volume(closed)), 0.08);
  CHECK(rep.repair.distance.mean < 0.01 * rep.check.diagonal);
  // Far from the input only across the patched holes.
  CHECK(rep.repair.distance.max <= rep.check.largest_hole_radius + 2 * rep.repair.voxel);
}
