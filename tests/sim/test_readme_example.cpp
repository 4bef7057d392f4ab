// The README's library example, compiled and checked so the README stays true.
#include <catch2/catch.hpp>

#include <cstdio>

// README example begins
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "sim/fem/fem_simulation.h"

double readme_example(const std::string& path) {
  using namespace incise;
  write_tet_mesh(make_box(Vec3(0.1, 0.02, 0.02), {20, 4, 4}), path);
  TetMesh mesh = read_tet_mesh(path);  // any format, by extension

  FemSimulationOptions opt;
  opt.kind = FemKind::Corotational;
  opt.cg.tolerance = 1e-8;
  opt.cg.budget_ms = 0;  // no per-frame wall-clock budget
  FemSimulation fem(mesh, MaterialTable(Material{1e5, 0.45, 1000}), opt);
  for (VertexId v : mesh.vertices())
    if (mesh.rest(v).x() == 0) fem.fix(v);           // clamp x = 0
    else if (mesh.rest(v).x() > 0.0999) fem.set_force(v, Vec3(0, 0, -1e-3));
  fem.step();                                        // solve K u = f (warm-started CG)

  // Edit the mesh locally, then hand the one change record to the backend.
  TetId t = mesh.tets().front();
  mesh.split_tet(t);
  fem.apply(mesh.take_change());                     // O(change), not O(mesh)
  const FrameStats& s = fem.step();
  mesh.validate({.check_orientation = true, .check_manifold_boundary = true});
  return s.relative_residual;
}
// README example ends

TEST_CASE("the README's library example runs", "[readme]") {
  const std::string path = std::string(INCISE_BINARY_DIR) + "/readme_example.vtu";
  CHECK(readme_example(path) <= 1e-8);
  std::remove(path.c_str());
}
