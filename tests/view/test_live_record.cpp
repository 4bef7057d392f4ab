// Record in live mode: a take writes the frames played while recording and scene.json, the
// scene with the inputs the page gave since the start; `incise simulate` replays that to the
// same run (the same cut mesh, the same displacements in the recorded frames).
#include <catch2/catch.hpp>

#include <chrono>
#include <filesystem>
#include <thread>

#include <nlohmann/json.hpp>

#include "mesh/io/tet_io.h"
#include "scene/run_scene.h"
#include "live_test_util.h"
#include "view/live_session.h"

using namespace incise;
using namespace incise::view;
using namespace incise::view::testing;
namespace fs = std::filesystem;

namespace {

const char* kBeam = R"({
  "mesh": {"generate": "box", "size": [4, 1, 1], "cells": [12, 3, 3]},
  "model": "fem-corotational",
  "materials": {"*": {"young": 1e4, "poisson": 0.3, "density": 1}},
  "fixed": [{"box": [-0.01, -1, -1, 0.01, 2, 2]}],
  "loads": [{"type": "gravity", "g": [0, 0, -1]}],
  "solver": {"method": "cg", "tolerance": 1e-10, "max_iterations": 5000, "preconditioner": "block-jacobi"},
  "time": {"frames": 40}
})";

}  // namespace

TEST_CASE("live record: a take replays to the same run", "[view]") {
  const Scene scene = parse_scene(kBeam, "beam.json");
  {
    LiveSession no_dir(scene);
    CHECK(no_dir.post(msg(InputKind::Record, {}, 1)) == "record: start incise view with --record DIR to record takes");
  }
  const fs::path dir = fs::temp_directory_path() / "incise_live_record";
  fs::remove_all(dir);
  // A --record path whose parent does not exist either is refused up front (not at Record).
  CHECK_THROWS_WITH(LiveSession(scene, (dir / "no" / "such").string()),
                    Catch::Contains("--record: neither this directory nor its parent"));
  CHECK_FALSE(fs::exists(dir));
  LiveSession live(scene, dir.string());
  REQUIRE(live.post(msg(InputKind::Pause)).empty());
  live.start();
  auto step = [&] {
    const int f = status(live)["frame"].get<int>();
    REQUIRE(live.post(msg(InputKind::Step)).empty());
    wait_for(live, [&](const nlohmann::json& j) { return j["frame"].get<int>() == f + 1; });
  };
  step();  // frame 0 before the take: the replay plays it too
  REQUIRE(live.post(msg(InputKind::Record, {}, 1)).empty());
  wait_for(live, [](const nlohmann::json& j) { return j["recording"] == "take-1"; });
  step();
  // A blade from the top at x = 1.3, down to 0.45 over three moves, then withdrawn.
  REQUIRE(live.post(msg(InputKind::BladeStart, {1.3f, -0.5f, 1.2f, 1.3f, 1.5f, 1.2f})).empty());
  for (int k = 1; k <= 3; ++k) {
    const float z = 1.2f - 0.25f * float(k);
    REQUIRE(live.post(msg(InputKind::BladeMove, {1.3f, -0.5f, z, 1.3f, 1.5f, z})).empty());
    wait_for(live, [&](const nlohmann::json& j) { return j["blade_steps"].get<int>() == k; });
    step();
  }
  REQUIRE(live.post(msg(InputKind::BladeEnd)).empty());
  REQUIRE(live.post(msg(InputKind::ProbeGrab, {4, 0.5f, 1, 0.3f})).empty());
  REQUIRE(live.post(msg(InputKind::ProbeMove, {0, 0, 0.1f})).empty());
  step();
  step();
  REQUIRE(live.post(msg(InputKind::Record, {}, 0)).empty());
  wait_for(live, [](const nlohmann::json& j) { return j["recording"] == "" && j["last_take"] != ""; });
  const nlohmann::json end = status(live);
  live.stop();

  const fs::path take = dir / "take-1";
  REQUIRE(end["last_take"] == take.string());
  for (const char* f : {"scene.json", "frames.pvd", "stats.csv"}) CHECK(fs::exists(take / f));
  const int last = end["frame"].get<int>() - 1;  // the last frame played
  CHECK(last == 6);
  for (int f = 1; f <= last; ++f) CHECK(fs::exists(take / ("frame_000" + std::to_string(f) + ".vtu")));
  CHECK_FALSE(fs::exists(take / "frame_0000.vtu"));  // before the take

  // The replay: the whole run from frame 0, the same mesh and the same last frame.
  SceneRunOptions ro;
  ro.out_dir = (dir / "replay").string();
  const Scene rec = load_scene((take / "scene.json").string());
  CHECK(rec.frames == last + 1);
  const SceneRunSummary sum = run_scene(rec, ro);
  CHECK(sum.tets == end["tets"].get<std::size_t>());
  CHECK(sum.tets > 12 * 3 * 3 * 6);  // the blade cut
  const std::string name = "frame_000" + std::to_string(last) + ".vtu";
  const TetMesh a = read_tet_mesh((take / name).string()), b = read_tet_mesh((dir / "replay" / name).string());
  REQUIRE(a.num_vertices() == b.num_vertices());
  double worst = 0;
  for (VertexId v : a.vertices()) worst = std::max(worst, (a.rest(v) - b.rest(v)).norm());
  CHECK(worst < 1e-9);  // positions written as floats in binary VTU: equal, not just close
}
