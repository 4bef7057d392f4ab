// Consumer of the installed package: builds a box, writes and reads it back, reports its
// quality (the JSON writer the CLI uses) and runs a few FEM frames of a clamped beam under
// a tip load, then cuts it, and steps a scene (incise::scene). Exits 1 with a message when an answer is wrong, so the CTest test can fail.
#include <cmath>
#include <cstdio>
#include <string>

#include "cut/cutter.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "quality/report.h"
#include "quality/report_json.h"
#include "scene/scene_runner.h"
#include "sim/fem/fem_simulation.h"
#ifdef CONSUMER_HAVE_TETRA
#include "mesh/tetrahedralize/tetrahedralize.h"
#endif

namespace {

int failures = 0;

void check(bool ok, const std::string& what) {
  std::printf("%s: %s\n", ok ? "ok" : "FAILED", what.c_str());
  if (!ok) ++failures;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace incise;
  const std::string path = argc > 1 ? argv[1] : "consumer_box.vtu";
  write_tet_mesh(make_box(Vec3(1.0, 0.2, 0.2), {10, 2, 2}), path);
  TetMesh mesh = read_tet_mesh(path);
  mesh.validate({.check_orientation = true, .check_manifold_boundary = true});
  check(mesh.num_tets() == 6 * 10 * 2 * 2, "box read back with 240 tets");
  check(std::abs(mesh.total_volume() - 0.04) < 1e-12, "box volume 0.04");

  const QualityReport q = compute_quality_report(mesh);
  const nlohmann::json j = quality_report_json(q);
  check(j["schema"] == "incise.quality/1", "quality JSON schema");
  const double mean_ratio_min = q.stats(Metric::MeanRatio).min;
  check(std::abs(mean_ratio_min - 0.755953) < 1e-5, "Kuhn tets: mean ratio 0.755953");
  check(q.boundary.closed() && q.components == 1, "closed boundary, one component");
#ifdef CONSUMER_HAVE_TETRA
  const auto [dmin, dmax] = dihedral_range(mesh);
  check(std::abs(dmin - 45) < 1e-9 && std::abs(dmax - 90) < 1e-9, "tetra: Kuhn dihedral range 45..90");
#endif

  FemSimulationOptions opt;
  opt.cg.tolerance = 1e-10;
  FemSimulation fem(mesh, MaterialTable(Material{1e5, 0.3, 1000}), opt);
  for (VertexId v : mesh.vertices()) {
    if (mesh.rest(v).x() == 0) fem.fix(v);
    else if (mesh.rest(v).x() == 1.0) fem.set_force(v, Vec3(0, 0, -1e-3));
  }
  int first_iterations = 0;
  double tip = 0;
  for (int frame = 0; frame < 3; ++frame) {
    const FrameStats& s = fem.step();
    if (frame == 0) first_iterations = s.iterations;
    check(s.info == SolveInfo::Success && s.relative_residual <= 1e-10, "frame " + std::to_string(frame) + " converged");
    if (frame > 0) check(s.iterations < first_iterations, "frame " + std::to_string(frame) + " warm-started");
    tip = 0;
    for (VertexId v : mesh.vertices())
      if (mesh.rest(v).x() == 1.0) tip = std::min(tip, fem.displacement()[3 * v.idx() + 2]);
  }
  check(tip < 0, "tip deflects along the load");

  // A partial cut from the top at mid-length (incise::cut, with the local improvement of
  // incise::quality), handed to the FEM model locally.
  mesh.discard_change();
  Cutter cutter(mesh);
  cutter.start({Vec3(0.503, -0.1, 0.3), Vec3(0.503, 0.3, 0.3)});
  const CutStepReport r = cutter.advance({Vec3(0.503, -0.1, 0.1), Vec3(0.503, 0.3, 0.1)});
  fem.apply(r.change);
  // The blade withdrawn: the tets it stopped in are cut too (one more local change).
  const CutStepReport fin = cutter.finish();
  fem.apply(fin.change);
  check(r.vertices_duplicated + fin.vertices_duplicated > 0 && fem.step().info == SolveInfo::Success,
        "cut, applied locally, solved");
  mesh.validate({.check_orientation = true, .check_manifold_boundary = true});

  // The same beam as a scene, played frame by frame with a probe on the tip from outside.
  SceneRunner runner(parse_scene(R"({"mesh": {"generate": "box", "size": [1, 0.2, 0.2], "cells": [10, 2, 2]},
    "fixed": [{"box": [0, 0, 0, 0, 0.2, 0.2]}], "time": {"frames": 2}})", "consumer.json"));
  runner.set_probe(runner.vertices_near(Vec3(1, 0.1, 0.1), 0.15), Vec3(0, 0, -0.01));
  const SceneFrame sf = runner.step();
  check(sf.stats.info == SolveInfo::Success && sf.max_displacement > 0.01 - 1e-9 && sf.max_displacement < 0.011, "scene stepped with a probe");
  std::remove(path.c_str());
  std::printf("consumer: %d failure(s), tip deflection %.6g\n", failures, tip);
  return failures == 0 ? 0 : 1;
}
