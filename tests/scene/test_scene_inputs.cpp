// Scene "inputs": what a hand gave between frames (a viewer's blade and probe), recorded by the
// runner, written back into the scene (scene/scene_record.h) and replayed by `incise simulate`.
// The replay must be the same run: same input in the same order before the same frames, so the
// same cuts and the same displacements.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <string>

#include "mesh/errors.h"
#include "scene/run_scene.h"
#include "scene/scene_record.h"
#include "scene/scene_runner.h"

using namespace incise;
namespace fs = std::filesystem;

namespace {

// A 4 x 1 x 1 beam clamped at x = 0 under gravity, with its own blade over frames 6..7 (the
// recorded input must keep its place before the scene's cuts); `extra` adds keys.
std::string beam_text(const std::string& extra = "") {
  return R"({
  "mesh": {"generate": "box", "size": [4, 1, 1], "cells": [12, 3, 3]},
  "model": "fem-corotational",
  "materials": {"*": {"young": 1e4, "poisson": 0.3, "density": 1}},
  "fixed": [{"box": [-0.01, -1, -1, 0.01, 2, 2]}],
  "loads": [{"type": "gravity", "g": [0, 0, -1]}],
  "cuts": [{"blade": [[3.1, -0.5, 1.2], [3.1, 1.5, 1.2]], "sweep": [0, 0, -0.5], "from_frame": 6, "to_frame": 7}],
  "solver": {"method": "cg", "tolerance": 1e-10, "max_iterations": 5000, "preconditioner": "block-jacobi"},
  "time": {"frames": 10})" + extra + "}";
}

// The hand: a probe grabbed at the tip and pulled up, a blade entering from the top at x = 1.3
// over frames 2..4 (two steps before frame 3), withdrawn before frame 5, the probe let go
// before frame 8. Plays `frames` frames; returns the displacement of each.
std::vector<Eigen::VectorXd> play_by_hand(SceneRunner& run, int frames) {
  std::vector<Eigen::VectorXd> out;
  for (int f = 0; f < frames; ++f) {
    if (f == 1) REQUIRE(run.grab_probe(Vec3(4, 0.5, 1), 0.3) > 0);
    if (f == 1 || f == 3) run.move_probe(Vec3(0, 0, 0.05 * f));
    if (f == 2) run.advance_blade({Vec3(1.3, -0.5, 1.2), Vec3(1.3, 1.5, 1.2)});
    if (f == 3) {
      run.advance_blade({Vec3(1.3, -0.5, 1.0), Vec3(1.3, 1.5, 1.0)});
      run.advance_blade({Vec3(1.3, -0.5, 0.8), Vec3(1.3, 1.5, 0.8)});
    }
    if (f == 4) run.advance_blade({Vec3(1.3, -0.5, 0.55), Vec3(1.3, 1.5, 0.55)});
    if (f == 5) run.finish_blade();
    if (f == 8) run.release_probe();
    out.push_back(run.step().displacement);
  }
  return out;
}

fs::path inputs_temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("incise_scene_inputs_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string inputs_error_of(const std::string& text) {
  try {
    parse_scene(text, "rec.json");
  } catch (const IoError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST_CASE("scene inputs: a run by hand, written back as a scene, replays to the same run", "[scene]") {
  const Scene scene = parse_scene(beam_text(), "beam.json");
  SceneRunner hand(scene);
  const std::size_t tets0 = hand.mesh().num_tets();
  const auto by_hand = play_by_hand(hand, scene.frames);
  REQUIRE(hand.replayable());
  REQUIRE(hand.mesh().num_tets() > tets0);  // both blades cut
  // grab, 2 moves, 4 blade inputs (1 placing), finish, release
  REQUIRE(hand.inputs_applied().size() == 9);

  const std::string text = recorded_scene_json(scene, {hand.inputs_applied(), hand.frame(), -1});
  const Scene rec = parse_scene(text, "rec.json");
  CHECK(rec.frames == scene.frames);
  REQUIRE(rec.inputs.size() == 9);
  CHECK(rec.inputs[0].kind == SceneInput::Kind::Grab);
  CHECK(rec.inputs[0].frame == 1);
  CHECK(rec.inputs[3].frame == 3);  // the second and third blade inputs, both before frame 3
  CHECK(rec.inputs[4].frame == 3);
  CHECK(rec.inputs[8].kind == SceneInput::Kind::Release);

  SceneRunner replay(rec);
  std::vector<Eigen::VectorXd> replayed;
  for (int f = 0; f < rec.frames; ++f) replayed.push_back(replay.step().displacement);
  CHECK(replay.mesh().num_tets() == hand.mesh().num_tets());
  CHECK(replay.mesh().num_vertices() == hand.mesh().num_vertices());
  REQUIRE(replayed.size() == by_hand.size());
  for (std::size_t f = 0; f < by_hand.size(); ++f) {
    INFO("frame " << f);
    REQUIRE(replayed[f].size() == by_hand[f].size());
    CHECK((replayed[f] - by_hand[f]).norm() <= 1e-9 * std::max(1e-12, by_hand[f].norm()));
  }
  // The probe pulled the tip up while held, and the replay records what it replayed: a second
  // recording is the first.
  CHECK(recorded_scene_json(rec, {replay.inputs_applied(), replay.frame(), -1}) == text);

  // Through a file, as `incise simulate` reads and writes it: same final state. (Writing the
  // frames once changed the run: the stress output refreshed the solver's rotations.)
  const fs::path dir = inputs_temp_dir("file");
  std::ofstream(dir / "rec.json") << text;
  SceneRunOptions ro;
  ro.out_dir = (dir / "out").string();
  const SceneRunSummary sum = run_scene(load_scene((dir / "rec.json").string()), ro);
  CHECK(sum.tets == hand.mesh().num_tets());
}

TEST_CASE("scene inputs: a recording that stops early, or after input, keeps what it needs", "[scene]") {
  const Scene scene = parse_scene(beam_text(), "beam.json");
  SceneRunner hand(scene);
  play_by_hand(hand, 3);  // frames 0..2 played, the blade placed before frame 2
  hand.advance_blade({Vec3(1.3, -0.5, 0.9), Vec3(1.3, 1.5, 0.9)});  // a step after the last frame
  const Scene rec = parse_scene(recorded_scene_json(scene, {hand.inputs_applied(), hand.frame(), 30}), "rec.json");
  // The scene's own blade (frames 6..7) had not started: it is left out, and the input after
  // frame 2 comes before one more frame.
  CHECK(rec.frames == 4);
  CHECK(rec.cuts.empty());
  CHECK(rec.inputs.back().frame == 3);
  // Stopped while the scene's blade moved (after frame 6): the replay plays on to its end.
  SceneRunner longer(scene);
  play_by_hand(longer, 7);
  const Scene rec7 = parse_scene(recorded_scene_json(scene, {longer.inputs_applied(), longer.frame(), -1}), "rec.json");
  CHECK(rec7.frames == 8);
  CHECK(rec7.cuts.size() == 1);
  CHECK(rec.cg.budget_ms == 30);
  // A mesh file's name becomes absolute: the recording is read from elsewhere.
  const Scene file_scene = parse_scene(R"({"mesh": "../liver.msh", "time": {"frames": 2}})", "/data/scenes/s.json");
  const std::string moved = recorded_scene_json(file_scene, {{}, 2, -1});
  CHECK_THAT(moved, Catch::Contains("\"mesh\": \"/data/liver.msh\""));
  // A scene made in code has no text to write back.
  Scene coded = scene;
  coded.source.clear();
  CHECK_THROWS_AS(recorded_scene_json(coded, {{}, 1, -1}), InvalidArgument);
}

TEST_CASE("scene inputs: inputs a scene cannot say make the run not replayable", "[scene]") {
  const Scene scene = parse_scene(beam_text(), "beam.json");
  SceneRunner a(scene);
  a.grab_probe(Vec3(4, 0.5, 1), 0.3);
  CHECK(a.replayable());
  a.set_probe({VertexId(3)}, Vec3(0, 0, 0.1));
  CHECK_FALSE(a.replayable());
  SceneRunner b(scene);
  CutOptions o;
  o.frozen = {VertexId(0)};
  b.advance_blade({Vec3(1.3, -0.5, 1.2), Vec3(1.3, 1.5, 1.2)}, o);
  CHECK_FALSE(b.replayable());
}

TEST_CASE("scene inputs: bad inputs are refused naming the key", "[scene][errors]") {
  auto with = [](const std::string& inputs) { return beam_text(", \"inputs\": " + inputs); };
  CHECK(inputs_error_of(with(R"([{"frame": 2, "blade": [[0, 0, 2], [1, 0, 2]]}, {"frame": 3, "finish": true}])")) == "(no error)");
  CHECK_THAT(inputs_error_of(with("{}")), Catch::Contains("inputs: expected an array"));
  CHECK_THAT(inputs_error_of(with(R"([{"blade": [[0, 0, 2], [1, 0, 2]]}])")), Catch::Contains("inputs[0].frame: missing"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 10, "finish": true}])")), Catch::Contains("inputs[0].frame: frame 10 is after the run's last frame (9)"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3, "finish": true}, {"frame": 2, "finish": true}])")),
             Catch::Contains("inputs[1].frame: inputs must be in frame order"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3, "finish": true, "release": true}])")), Catch::Contains("inputs[0]: expected exactly one of"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3}])")), Catch::Contains("inputs[0]: expected exactly one of"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3, "finish": false}])")), Catch::Contains("inputs[0].finish: expected true"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3, "blade": [[0, 0, 2], [0, 0, 2]]}])")), Catch::Contains("inputs[0].blade: the blade's two ends are the same point"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3, "blade": [[0, 0, 2]]}])")), Catch::Contains("inputs[0].blade: expected [[ax,ay,az],[bx,by,bz]]"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3, "blade": [[0, 0, 2], [1, 0, "x"]]}])")), Catch::Contains("inputs[0].blade[1]"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3, "grab": [4, 0.5, 1]}])")), Catch::Contains("inputs[0].radius: missing"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3, "grab": [4, 0.5, 1], "radius": -1}])")), Catch::Contains("inputs[0].radius: expected a positive number"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3, "probe": [0, 0, 1], "radius": 1}])")), Catch::Contains("inputs[0].radius: only for a grab input"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3, "finish": true, "snap": 0.1}])")), Catch::Contains("inputs[0].snap: only for a blade input"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3, "blade": [[0, 0, 2], [1, 0, 2]], "snap": 0.7}])")), Catch::Contains("inputs[0].snap"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3, "blade": [[0, 0, 2], [1, 0, 2]], "mode": "carve"}])")), Catch::Contains("inputs[0].mode: expected"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3, "probe": [0, 0, 1e999]}])")), Catch::Contains("rec.json"));
  CHECK_THAT(inputs_error_of(with(R"([{"frame": 3, "finish": true, "speed": 2}])")), Catch::Contains("inputs[0].speed: unknown key"));
}
