// Scenes that cannot lie: a static scene told to keep a part a cut freed is refused (a static
// solve has no equilibrium for it), a frame whose solution blew up stops the run naming the
// frame instead of being counted as converged, and a solve whose residual is not finite is
// never reported as converged.
//
// The cuts here are a test-local edit that severs the beam by removing one layer of tets and
// reports what lies beyond as a fragment, the way the cutter does (SceneRunner::edit between
// frames): that is all the runner's fragment rule sees.
#include <catch2/catch.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "sim/fem/fem_simulation.h"
#include "scene/run_scene.h"
#include "scene/scene_runner.h"

using namespace incise;
namespace fs = std::filesystem;

namespace {

// A 4 x 1 x 1 beam (cells of 0.5) clamped at x = 0, under gravity; `extra` is spliced in as
// further top-level keys.
Scene beam(const std::string& extra = "") {
  return parse_scene(R"({
  "mesh": {"generate": "box", "size": [4, 1, 1], "cells": [8, 2, 2]},
  "model": "fem-linear",
  "materials": {"*": {"young": 1e4, "poisson": 0.3, "density": 1}},
  "fixed": [{"box": [0, 0, 0, 0, 1, 1]}],
  "loads": [{"type": "gravity", "g": [0, 0, -1]}],
  "solver": {"method": "cg", "tolerance": 1e-8, "max_iterations": 5000},
  "time": {"frames": 4})" + extra + "}",
                     "scene.json");
}

constexpr std::size_t kBeamTets = 8 * 2 * 2 * 6;
constexpr std::size_t kLayerTets = 2 * 2 * 6;       // one cell layer across the beam
constexpr std::size_t kBeyondTets = 3 * 2 * 2 * 6;  // the three cell layers past x = 2.5

// Before `frame`'s solve, removes the tets between x = 2 and x = 2.5 (rest space): the beam's
// end beyond x = 2.5 is then a separate part with no fixed vertex, reported as a fragment.
std::function<void(SceneRunner&)> sever_at(int frame) {
  return [frame](SceneRunner& runner) {
    if (runner.frame() != frame) return;
    runner.edit([](TetMesh& mesh) {
      std::vector<TetId> beyond;
      for (TetId t : mesh.tets()) {
        Vec3 c = Vec3::Zero();
        for (VertexId v : mesh.tet_vertices(t)) c += mesh.rest(v) / 4;
        if (c.x() > 2 && c.x() < 2.5) mesh.remove_tet(t);
        else if (c.x() > 2.5) beyond.push_back(t);
      }
      return std::vector<std::vector<TetId>>{std::move(beyond)};
    });
  };
}

fs::path guards_temp_dir(const std::string& name) {
  fs::path p = fs::temp_directory_path() / ("incise_test_scene_guards_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  return p;
}

// Data rows of DIR/stats.csv: the frames the run computed.
int stats_rows(const fs::path& dir) {
  std::ifstream csv(dir / "stats.csv");
  int rows = -1;  // the header
  for (std::string line; std::getline(csv, line);) ++rows;
  return rows;
}

std::string error_of(const Scene& s, const SceneRunOptions& ro) {
  try {
    run_scene(s, ro);
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST_CASE("a static scene that keeps a part a cut freed is refused, naming the frame and the part", "[scene][guards]") {
  const fs::path out = guards_temp_dir("keep");
  SceneRunOptions ro;
  ro.out_dir = out.string();
  ro.before_frame = sever_at(2);
  const std::string e = error_of(beam(R"(, "fragments": "keep")"), ro);
  // 72 tets between x = 2.5 and 4, centred at (3.25, 0.5, 0.5).
  CHECK_THAT(e, Catch::StartsWith("scene.json: frame 2: a cut detached a part of " + std::to_string(kBeyondTets) +
                                  " tets near (3.25, 0.5, 0.5)"));
  CHECK_THAT(e, Catch::Contains("with no fixed vertex; a static solve has no equilibrium for it"));
  CHECK_THAT(e, Catch::Contains("\"remove\" or \"fix\", or use a dynamic integrator"));
  // Refused before frame 2's solve; frames 0 and 1 are kept.
  CHECK(stats_rows(out) == 2);
  CHECK(fs::exists(out / "frame_0001.vtu"));
  CHECK_FALSE(fs::exists(out / "frame_0002.vtu"));
  fs::remove_all(out);
}

TEST_CASE("the same severed scene runs with remove, fix, auto, and keeps the part when dynamic", "[scene][guards]") {
  SceneRunOptions ro;
  ro.before_frame = sever_at(2);
  SECTION("remove (and auto, which is remove for static FEM): the free part goes") {
    for (const char* policy : {"remove", "auto"}) {
      const SceneRunSummary sum = run_scene(beam(std::string(R"(, "fragments": ")") + policy + "\""), ro);
      CHECK(sum.frames == 4);
      CHECK(sum.frames_not_converged == 0);
      CHECK(sum.fragments_handled == 1);
      CHECK(sum.tets == kBeamTets - kLayerTets - kBeyondTets);
      // What stays is the clamped half: it sags less than the whole beam did.
      CHECK(sum.max_displacement > 0);
      CHECK(sum.max_displacement < run_scene(beam(), SceneRunOptions{}).max_displacement);
    }
  }
  SECTION("fix: the part is held where it is") {
    const SceneRunSummary sum = run_scene(beam(R"(, "fragments": "fix")"), ro);
    CHECK(sum.frames == 4);
    CHECK(sum.frames_not_converged == 0);
    CHECK(sum.tets == kBeamTets - kLayerTets);
  }
  SECTION("keep in dynamic FEM and springs: the part falls, legitimately") {
    Scene s = beam(R"(, "fragments": "keep")");
    s.integrator = "implicit-euler";
    SceneRunSummary sum = run_scene(s, ro);
    CHECK(sum.frames == 4);
    CHECK(sum.tets == kBeamTets - kLayerTets);
    CHECK(std::isfinite(sum.max_displacement));
    s.model = SceneModel::Springs;
    sum = run_scene(s, ro);
    CHECK(sum.frames == 4);
    CHECK(sum.tets == kBeamTets - kLayerTets);
  }
}

TEST_CASE("a frame whose solution blew up stops the run, naming the frame", "[scene][guards]") {
  const fs::path out = guards_temp_dir("blowup");
  SceneRunOptions ro;
  ro.out_dir = out.string();
  SECTION("static FEM: a tip load far beyond the material, from frame 2") {
    // CG converges on it (the problem is linear): only the size of the answer shows it.
    const Scene s = beam(R"(, "loads": [{"type": "force", "box": [4, 0, 0, 4, 1, 1], "total": [0, 0, -1e20],
                                        "from_frame": 2, "to_frame": 2}])");
    const std::string e = error_of(s, ro);
    const std::string head = "scene.json: frame 2: the solution blew up (max displacement ";
    REQUIRE_THAT(e, Catch::StartsWith(head));
    CHECK_THAT(e, Catch::Contains("x the body's size)"));
    // The reported displacement is the tip's: beam theory F L^3 / (3 E I) = 2.6e18 m (the coarse
    // linear tets are stiffer).
    const double tip = 1e20 * 64 / (3 * 1e4 * (1.0 / 12));
    const double reported = std::stod(e.substr(head.size()));
    CHECK(reported > 0.3 * tip);
    CHECK(reported < 1.2 * tip);
    CHECK(stats_rows(out) == 2);
  }
  SECTION("static FEM, direct: a load whose residual overflows is not a converged frame") {
    const Scene s = beam(R"(, "solver": {"method": "direct"},
      "loads": [{"type": "force", "box": [4, 0, 0, 4, 1, 1], "total": [0, 0, -9e200]}])");
    CHECK_THAT(error_of(s, ro), Catch::StartsWith("scene.json: frame 0: "));
    CHECK(stats_rows(out) == 0);
  }
  SECTION("springs: an explicit step far above the stable limit") {
    Scene s = beam();
    s.model = SceneModel::Springs;
    s.integrator = "explicit-euler";
    s.dt = 1;
    s.frames = 50;
    const std::string e = error_of(s, ro);
    CHECK_THAT(e, Catch::StartsWith("scene.json: frame "));
    CHECK_THAT(e, Catch::Contains(": the solution blew up ("));
    CHECK_THAT(e, Catch::Contains("time.dt"));
  }
  fs::remove_all(out);
}

TEST_CASE("a solve whose residual is not finite is not converged", "[fem][guards]") {
  // Forces of 1e200 on the tip of a clamped beam: the displacement (~1e200) is finite, but the
  // norms of the residual and of the right-hand side overflow, so nothing vouches for it.
  auto solve = [](double force, SolverMethod method) {
    const TetMesh m = make_box(Vec3(4, 1, 1), {8, 2, 2});
    FemSimulationOptions o;
    o.method = method;
    FemSimulation sim(m, MaterialTable(Material{1e4, 0.3, 1}), o);
    for (VertexId v : m.vertices()) {
      if (m.rest(v).x() == 0) sim.fix(v);
      if (m.rest(v).x() == 4) sim.set_force(v, Vec3(0, 0, -force));
    }
    return sim.step();
  };
  for (SolverMethod method : {SolverMethod::Direct, SolverMethod::Cg}) {
    const FrameStats ok = solve(1, method);
    CHECK(ok.info == SolveInfo::Success);
    CHECK(std::isfinite(ok.relative_residual));
    const FrameStats huge = solve(1e200, method);
    CHECK(huge.info == SolveInfo::NumericalIssue);
    CHECK_FALSE(huge.message.empty());
  }
}
