// The README's cutting example, compiled and checked so the README stays true.
#include <catch2/catch.hpp>

#include "quality/components.h"

// README cut example begins
#include "cut/cutter.h"
#include "mesh/generate.h"
#include "sim/fem/fem_simulation.h"

incise::TetMesh readme_cut_example() {
  using namespace incise;
  TetMesh mesh = make_box(Vec3(4, 1, 1), {16, 4, 4});
  mesh.discard_change();                   // the cutter starts from a mesh with no pending edits
  FemSimulationOptions opt;
  opt.gravity = Vec3(0, 0, -1);
  FemSimulation fem(mesh, MaterialTable(Material{1e4, 0.3, 1}), opt);
  for (VertexId v : mesh.vertices())
    if (mesh.rest(v).x() == 0) fem.fix(v);  // a cantilever clamped at x = 0
  fem.step();

  // A blade across the beam at x = 2.03 goes down 0.6 in 5 frames, cutting the sagging beam.
  const Vec3 a(2.03, -0.5, 1.1), b(2.03, 1.5, 1.1);
  Cutter cutter(mesh);                      // subdivide, snap 0.05, local improvement
  cutter.start({a, b});
  auto current = [&](VertexId v) {           // cut the deformed shape
    return Vec3(mesh.rest(v) + fem.displacement().segment<3>(3 * v.idx()));
  };
  for (int frame = 1; frame <= 5; ++frame) {
    const Vec3 down(0, 0, -0.12 * frame);
    CutStepReport r = cutter.advance({a + down, b + down}, current);
    fem.apply(r.change);                    // O(cut), not O(mesh)
    fem.step();
  }
  fem.apply(cutter.finish(current).change);  // blade withdrawn: the tets it stopped in are cut
  fem.step();
  return mesh;
}
// README cut example ends

TEST_CASE("the README's cutting example runs and leaves a valid, partially cut mesh", "[cut][readme]") {
  const incise::TetMesh m = readme_cut_example();
  REQUIRE_NOTHROW(m.validate({true, true}));
  CHECK(m.num_tets() > 16 * 4 * 4 * 6);
  CHECK(incise::tet_components(m).count == 1);  // a partial cut: still one piece
  // ... open over what the blade swept inside the beam, 1 x 0.5 on both sides (measured at rest:
  // the cut was made in the sagging shape, which moves it by a few percent).
  double area = 0;
  for (const auto& f : m.boundary_faces())
    if (f.tag == incise::kTagCut)
      area += 0.5 * (m.rest(f.vertices[1]) - m.rest(f.vertices[0])).cross(m.rest(f.vertices[2]) - m.rest(f.vertices[0])).norm();
  CHECK(area == Approx(1.0).epsilon(0.05));
}
