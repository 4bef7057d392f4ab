// SceneRunner: a scene played one frame at a time gives what run_scene gives, and input from
// outside between frames (a blade on the deformed body, a probe) reaches the mesh and the
// backend the way the scene's own blades and probes do.
#include <catch2/catch.hpp>

#include <string>
#include <vector>

#include "mesh/errors.h"
#include "scene/run_scene.h"
#include "scene/scene_runner.h"

using namespace incise;

namespace {

// A 4 x 1 x 1 beam clamped at x = 0 under gravity; `extra` is spliced in as further keys.
Scene runner_beam(const std::string& extra = "") {
  return parse_scene(R"({
  "mesh": {"generate": "box", "size": [4, 1, 1], "cells": [8, 2, 2]},
  "model": "fem-linear",
  "materials": {"*": {"young": 1e4, "poisson": 0.3, "density": 1}},
  "fixed": [{"box": [-0.01, -1, -1, 0.01, 2, 2]}],
  "loads": [{"type": "gravity", "g": [0, 0, -1]}],
  "solver": {"method": "cg", "tolerance": 1e-10, "max_iterations": 5000},
  "time": {"frames": 6})" + extra + "}",
                     "scene.json");
}

// Per frame: the displacement run_scene reports.
std::vector<Eigen::VectorXd> run_all(const Scene& s) {
  std::vector<Eigen::VectorXd> out;
  SceneRunOptions ro;
  ro.on_frame = [&](int, const Eigen::VectorXd& d, const FrameStats&) { out.push_back(d); };
  run_scene(s, ro);
  return out;
}

double max_abs_difference(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  REQUIRE(a.size() == b.size());
  return (a - b).cwiseAbs().maxCoeff();
}

}  // namespace

TEST_CASE("stepping a scene frame by frame gives run_scene's frames", "[scene][runner]") {
  // A probe ramped over frames 1..4 and a blade cutting in over frames 2..3: every frame differs.
  const Scene s = runner_beam(R"(, "loads": [{"type": "gravity", "g": [0, 0, -1]},
      {"type": "probe", "box": [4, 0, 0, 4, 1, 1], "displacement": [0, 0, -0.2], "from_frame": 1, "to_frame": 4}],
    "cuts": [{"blade": [[2.03, -0.5, 1.2], [2.03, 1.5, 1.2]], "sweep": [0, 0, -0.6], "from_frame": 2, "to_frame": 3}])");
  const std::vector<Eigen::VectorXd> whole = run_all(s);
  REQUIRE(whole.size() == 6);

  SceneRunner runner(s);
  const std::size_t tets_before = runner.mesh().num_tets();
  for (int k = 0; k < 6; ++k) {
    CHECK(runner.frame() == k);
    const SceneFrame f = runner.step();
    CHECK(f.frame == k);
    CHECK(f.time == k);  // static: the frame number
    CHECK(f.stats.info == SolveInfo::Success);
    CHECK(max_abs_difference(f.displacement, whole[std::size_t(k)]) < 1e-9);
    CHECK(f.max_displacement > 0);
    // Before the blade nothing is cut; after it (frames 4, 5) the withdrawn blade's
    // improvement may still run its slices (SceneRunner::kFinishImproveSlice).
    if (k == 2 || k == 3) CHECK(f.cut_ms > 0);
    else if (k < 2) CHECK(f.cut_ms == 0);
  }
  CHECK(runner.mesh().num_tets() > tets_before);
  // The positions are the rest ones plus the last frame's displacement.
  const std::vector<Vec3> x = runner.positions();
  for (VertexId v : runner.mesh().vertices())
    CHECK((x[v.idx()] - runner.mesh().rest(v) - whole[5].segment<3>(3 * v.idx())).norm() < 1e-9);
}

TEST_CASE("a blade advanced from outside between frames cuts the deformed beam like a scene blade", "[scene][runner][cut]") {
  // The scene's own through-cut at frame 1 (test_scene_cuts) against the same sweep from outside.
  const std::string cut = R"(, "cuts": [{"blade": [[2.03, -0.5, 1.3], [2.03, 1.5, 1.3]], "sweep": [0, 0, -1.6],
                                         "from_frame": 1, "to_frame": 1}])";
  SceneRunOptions none;
  const SceneRunSummary scripted = run_scene(runner_beam(cut), none);
  REQUIRE(scripted.fragments_handled == 1);

  SceneRunner runner(runner_beam());
  const SceneFrame first = runner.step();
  const std::size_t tets = runner.mesh().num_tets();
  // Placed, then swept down through the body in two moves (the beam sags under gravity: the
  // blade cuts its current shape).
  CHECK(runner.advance_blade({Vec3(2.03, -0.5, 1.3), Vec3(2.03, 1.5, 1.3)}).change.empty());
  // Halfway the opening may still wait for the blade to leave the tets it is in (cut/cutter.h).
  runner.advance_blade({Vec3(2.03, -0.5, 0.2), Vec3(2.03, 1.5, 0.2)});
  CHECK(runner.fragments_handled() == 0);
  // The backend follows each change: its state covers the new vertices.
  REQUIRE(runner.fem());
  CHECK(runner.fem()->displacement().size() >= Eigen::Index(3 * runner.mesh().vertex_capacity()));
  const SceneFrame mid = runner.step();
  CHECK(mid.stats.info == SolveInfo::Success);
  runner.advance_blade({Vec3(2.03, -0.5, -0.3), Vec3(2.03, 1.5, -0.3)});
  runner.finish_blade();
  // Through: the free end goes (static FEM, auto = remove), as with the scene's blade.
  CHECK(runner.fragments_handled() == 1);
  CHECK(runner.mesh().num_tets() < tets);
  CHECK(runner.total_cut_ms() > 0);
  SceneFrame last;
  while (runner.frame() < 6) last = runner.step();
  CHECK(last.stats.info == SolveInfo::Success);
  CHECK(runner.mesh().num_tets() == scripted.tets);
  CHECK(last.max_displacement == Approx(scripted.max_displacement).epsilon(0.05));
  CHECK(last.max_displacement < first.max_displacement);  // a 2-long cantilever sags less
}

TEST_CASE("a probe set from outside holds the vertices it grabs until released", "[scene][runner]") {
  SceneRunner runner(runner_beam());
  const SceneFrame sag = runner.step();
  // The free end's vertices, grabbed around where it hangs now (it sags by a few hundredths).
  const std::vector<VertexId> grabbed = runner.vertices_near(Vec3(4, 0.5, 0.5), 0.8);
  REQUIRE(!grabbed.empty());
  for (VertexId v : grabbed) CHECK(runner.mesh().rest(v).x() > 3.2);
  runner.set_probe(grabbed, Vec3(0, 0, 0.3));
  const SceneFrame lifted = runner.step();
  for (VertexId v : grabbed) CHECK((lifted.displacement.segment<3>(3 * v.idx()) - Vec3(0, 0, 0.3)).norm() < 1e-12);
  // A clamped vertex is the scene's: a probe over it leaves it fixed.
  std::vector<VertexId> root = runner.vertices_near(Vec3(0, 0, 0), 1e-6);
  REQUIRE(root.size() == 1);
  runner.set_probe(root, Vec3(0, 0, 1));
  CHECK(runner.step().displacement.segment<3>(3 * root[0].idx()).norm() == 0);
  runner.release_probe();
  const SceneFrame again = runner.step();
  CHECK(max_abs_difference(again.displacement, sag.displacement) < 1e-6 * sag.max_displacement);
}

TEST_CASE("a runner checks the scene before the first frame", "[scene][runner][errors]") {
  CHECK_THROWS_WITH(SceneRunner(runner_beam(R"(, "fixed": [{"box": [9, 9, 9, 9, 9, 9]}])")),
                    Catch::Contains("scene.json: fixed[0].box: selects no vertex"));
  // A static FEM scene told to keep a part a blade from outside freed is refused, naming the frame.
  SceneRunner keep(runner_beam(R"(, "fragments": "keep")"));
  keep.step();
  keep.advance_blade({Vec3(2.03, -0.5, 1.3), Vec3(2.03, 1.5, 1.3)});
  CHECK_THROWS_WITH(keep.advance_blade({Vec3(2.03, -0.5, -0.3), Vec3(2.03, 1.5, -0.3)}),
                    Catch::StartsWith("scene.json: frame 1: a cut detached a part of"));
}
