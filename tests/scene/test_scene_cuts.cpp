// Scenes with cuts: blades advance over frames on the deformed body, the backends take each
// step locally, frames show the opening, and the fragments policy decides what a detached part
// of a static scene becomes.
#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "scene/run_scene.h"
#include "mesh/errors.h"
#include "mesh/io/tet_io.h"
#include "quality/components.h"

using namespace incise;
namespace fs = std::filesystem;

namespace {

// A 4 x 1 x 1 beam clamped at x = 0 under gravity; `cut` and `extra` are spliced in.
std::string beam_scene(const std::string& cut, const std::string& extra = "") {
  return R"({
  "mesh": {"generate": "box", "size": [4, 1, 1], "cells": [8, 2, 2]},
  "model": "fem-linear",
  "materials": {"*": {"young": 1e4, "poisson": 0.3, "density": 1}},
  "fixed": [{"box": [-0.01, -1, -1, 0.01, 2, 2]}],
  "loads": [{"type": "gravity", "g": [0, 0, -1]}],
  "solver": {"method": "cg", "tolerance": 1e-8, "max_iterations": 5000},
  "time": {"frames": 6},
  "cuts": [)" + cut + "]" + extra + "}";
}

fs::path cuts_temp_dir(const std::string& name) {
  fs::path d = fs::temp_directory_path() / ("incise_scene_cuts_" + name);
  fs::remove_all(d);
  return d;
}

// Plays s into a fresh temporary directory `name` (out: that directory).
SceneRunSummary run_in(const Scene& s, const std::string& name, fs::path& out) {
  out = cuts_temp_dir(name);
  SceneRunOptions ro;
  ro.out_dir = out.string();
  return run_scene(s, ro);
}

// The volume of the mesh a run wrote for a frame.
double frame_volume(const fs::path& out, const std::string& frame_file) {
  const TetMesh m = read_tet_mesh((out / frame_file).string());
  double volume = 0;
  for (TetId t : m.tets()) volume += m.volume(t);
  return volume;
}

}  // namespace

TEST_CASE("a partial cut over frames: the beam stays one piece, frames mark the cut faces", "[cut][scene]") {
  // The blade enters from the top at x = 2.03 and stops at mid-depth, over frames 1..3.
  const Scene s = parse_scene(
      beam_scene(R"({"blade": [[2.03, -0.5, 1.2], [2.03, 1.5, 1.2]], "sweep": [0, 0, -0.7], "from_frame": 1, "to_frame": 3})"),
      "scene.json");
  REQUIRE(s.cuts.size() == 1);
  fs::path out;
  const SceneRunSummary sum = run_in(s, "partial", out);
  CHECK(sum.frames == 6);
  CHECK(sum.frames_not_converged == 0);
  CHECK(sum.total_cut_ms > 0);
  CHECK(sum.fragments_handled == 0);
  CHECK(sum.tets > 8 * 2 * 2 * 6);
  CHECK(sum.warnings.empty());  // the blade met the body
  std::ifstream csv(out / "stats.csv");
  std::string header;
  std::getline(csv, header);
  CHECK(header.find("cut_ms,tets") != std::string::npos);
  // outside_ms (what the frame spent before the solver, taken off a budget) holds the cut.
  std::vector<std::string> names;
  {
    std::stringstream hs(header);
    for (std::string h; std::getline(hs, h, ',');) names.push_back(h);
  }
  auto col = [&](const std::string& n) { return std::size_t(std::find(names.begin(), names.end(), n) - names.begin()); };
  REQUIRE(col("outside_ms") < names.size());
  int cut_frames = 0;
  for (std::string row; std::getline(csv, row);) {
    std::vector<double> v;
    std::stringstream rs(row);
    for (std::string x; std::getline(rs, x, ',');) v.push_back(std::stod(x));
    REQUIRE(v.size() == names.size());
    CHECK(v[col("outside_ms")] >= v[col("cut_ms")]);
    cut_frames += v[col("cut_ms")] > 0;
  }
  CHECK(cut_frames >= 3);
  const TetMesh last = read_tet_mesh((out / "frame_0005.vtu").string());
  CHECK(last.num_tets() == sum.tets);
  CHECK(tet_components(last).count == 1);
  // The cut weakens the beam: it sags more than without the cut.
  const Scene uncut = parse_scene(beam_scene(""), "scene.json");
  SceneRunOptions none;
  CHECK(sum.max_displacement > run_scene(uncut, none).max_displacement * 1.01);
  CHECK(fs::file_size(out / "frame_0005.vtu") > 0);
  std::ifstream vtu(out / "frame_0005.vtu");
  const std::string text((std::istreambuf_iterator<char>(vtu)), std::istreambuf_iterator<char>());
  CHECK(text.find("cut_faces") != std::string::npos);
  fs::remove_all(out);
}

TEST_CASE("mid-cut, the provisional pieces open the cut up to the blade: the beam sags more", "[cut][scene]") {
  // The partial cut above stopped after frame 2, the blade halfway down: with the tets the
  // blade is in cut provisionally, the beam is open to the blade and weaker.
  auto run = [](const char* provisional) {
    const Scene s = parse_scene(beam_scene(std::string(R"({"blade": [[2.03, -0.5, 1.2], [2.03, 1.5, 1.2]], )") +
                                           R"("sweep": [0, 0, -0.7], "from_frame": 1, "to_frame": 3, "provisional": )" +
                                           provisional + "}"),
                                "scene.json");
    SceneRunOptions ro;
    ro.frames = 3;
    return run_scene(s, ro);
  };
  const SceneRunSummary with = run("true"), without = run("false");
  CHECK(with.frames_not_converged == 0);
  CHECK(with.max_displacement > without.max_displacement * 1.005);
  CHECK_THROWS_WITH(parse_scene(beam_scene(R"({"blade": [[0, 0, 0], [1, 0, 0]], "sweep": [0, 0, 1], "provisional": 1})"),
                                "s.json"),
                    Catch::Contains("cuts[0].provisional"));
}

TEST_CASE("a scene cut in the material frame detaches the beam's end as one in the current frame does", "[cut][scene]") {
  // docs/scene.md cuts[].material_frame: the beam sags under gravity while the blade goes through
  // it over frames 1-10; in either frame the free end comes off (the fragments policy removes it).
  // (tests/python/test_cut.py checks where the material frame puts the cut.)
  auto run = [](const char* frame) {
    std::string scene = beam_scene(std::string(R"({"blade": [[2.03, -0.5, 1.3], [2.03, 1.5, 1.3]], "sweep": [0, 0, -1.6], )") +
                                   R"("from_frame": 1, "to_frame": 10, "material_frame": )" + frame + "}");
    scene.replace(scene.find(R"("frames": 6)"), 11, R"("frames": 12)");
    SceneRunOptions ro;
    return run_scene(parse_scene(scene, "scene.json"), ro);
  };
  const SceneRunSummary rest = run("true"), current = run("false");
  CHECK(rest.fragments_handled == 1);
  CHECK(current.fragments_handled == 1);
  CHECK(rest.frames_not_converged == 0);
  CHECK(rest.max_displacement == Approx(current.max_displacement).epsilon(0.05));
  CHECK_THROWS_WITH(parse_scene(beam_scene(R"({"blade": [[0, 0, 0], [1, 0, 0]], "sweep": [0, 0, 1], "material_frame": 1})"),
                                "s.json"),
                    Catch::Contains("cuts[0].material_frame"));
}

TEST_CASE("a through-cut frees the beam's end: the fragments policy decides", "[cut][scene]") {
  const std::string cut = R"({"blade": [[2.03, -0.5, 1.3], [2.03, 1.5, 1.3]], "sweep": [0, 0, -1.6], "from_frame": 2, "to_frame": 2})";
  SceneRunOptions ro;
  {
    // Static FEM, default (auto = remove): the free half goes, the solve does not break down.
    const SceneRunSummary sum = run_scene(parse_scene(beam_scene(cut), "scene.json"), ro);
    CHECK(sum.fragments_handled == 1);
    CHECK(sum.frames_not_converged == 0);
    CHECK(sum.tets < 8 * 2 * 2 * 6);
  }
  {
    const SceneRunSummary sum =
        run_scene(parse_scene(beam_scene(cut, R"(, "fragments": "fix")"), "scene.json"), ro);
    CHECK(sum.fragments_handled == 1);
    CHECK(sum.frames_not_converged == 0);
    CHECK(sum.tets > 8 * 2 * 2 * 6);
  }
  CHECK_THROWS_WITH(run_scene(parse_scene(beam_scene(cut, R"(, "fragments": "error")"), "scene.json"), ro),
                    Catch::Contains("fragment"));
}

TEST_CASE("a through-cut over many frames detaches exactly like the same sweep in one frame", "[cut][scene]") {
  // The issue's case: the beam under gravity, cut through over frames 1..10 of 12.
  auto run = [](int to) {
    const std::string cut = R"({"blade": [[2.03, -0.5, 1.3], [2.03, 1.5, 1.3]], "sweep": [0, 0, -1.6], "from_frame": 1, )"
                            R"("to_frame": )" + std::to_string(to) + "}";
    std::string scene = beam_scene(cut);
    scene.replace(scene.find(R"("frames": 6)"), 11, R"("frames": 12)");
    SceneRunOptions ro;
    return run_scene(parse_scene(scene, "scene.json"), ro);
  };
  const SceneRunSummary one = run(1), many = run(10);
  CHECK(one.fragments_handled == 1);
  CHECK(many.fragments_handled == 1);
  CHECK(many.frames_not_converged == 0);
  // The same part stays; its tet count may differ by what the improvement after the cut did,
  // which works on the tets each step count made (finish() repairs all of a drag's slivers).
  CHECK(many.tets >= one.tets * 9 / 10);
  CHECK(many.tets <= one.tets * 11 / 10);
  // The clamped half alone: it sags like a 2-long cantilever, not like a part hanging by a vertex.
  CHECK(many.max_displacement == Approx(one.max_displacement).epsilon(0.05));
  CHECK(many.max_displacement < 0.1);
}

TEST_CASE("a blade that passes above the sagging body cuts nothing, and the summary says so", "[cut][scene]") {
  // Issue 39 item 2: the blade acts on the deformed shape; one that misses it is no error, but
  // a run that silently cut nothing is one a user cannot tell from a cut.
  const Scene s = parse_scene(
      beam_scene(R"({"blade": [[2.03, -0.5, 1.6], [2.03, 1.5, 1.6]], "sweep": [0, 0, -0.3], "from_frame": 1, "to_frame": 3})"),
      "scene.json");
  SceneRunOptions ro;
  const SceneRunSummary sum = run_scene(s, ro);
  REQUIRE(sum.warnings.size() == 1);
  CHECK_THAT(sum.warnings[0], Catch::StartsWith("cuts[0] (frames 1-3) cut nothing: its blade never met the body"));
  CHECK(sum.tets == 8 * 2 * 2 * 6);
  // Judged once the cut is over: a run stopped before its last frame says nothing yet.
  ro.frames = 3;
  CHECK(run_scene(s, ro).warnings.empty());
}

TEST_CASE("scene cut errors name the key", "[cut][scene][errors]") {
  CHECK_THROWS_WITH(parse_scene(beam_scene(R"({"blade": [[0, 0, 0]], "sweep": [0, 0, 1]})"), "s.json"),
                    Catch::Contains("cuts[0].blade"));
  CHECK_THROWS_WITH(parse_scene(beam_scene(R"({"blade": [[0, 0, 0], [1, 0, 0]]})"), "s.json"),
                    Catch::Contains("cuts[0].sweep"));
  CHECK_THROWS_WITH(parse_scene(beam_scene(R"({"blade": [[0, 0, 0], [1, 0, 0]], "sweep": [0, 0, 1], "blunt": 1})"),
                                "s.json"),
                    Catch::Contains("blunt"));
  CHECK_THROWS_WITH(parse_scene(beam_scene("", R"(, "fragments": "explode")"), "s.json"), Catch::Contains("fragments"));
  // A blade that would move after the last frame never cuts: refused when parsed.
  CHECK_THROWS_WITH(parse_scene(beam_scene(R"({"blade": [[2, 0, 1.2], [2, 1, 1.2]], "sweep": [0, 0, -1], "to_frame": 6})"),
                                "s.json"),
                    Catch::Contains("cuts[0].to_frame: frame 6 is after the run's last frame"));
  // ... and so is a load ramp (a probe that would never reach its displacement).
  {
    std::string s = beam_scene("");
    s.replace(s.find(R"({"type": "gravity", "g": [0, 0, -1]})"), std::string(R"({"type": "gravity", "g": [0, 0, -1]})").size(),
              R"({"type": "probe", "box": [3.9, -1, -1, 4.1, 2, 2], "displacement": [0, 0, -0.1], "from_frame": 0, "to_frame": 9})");
    CHECK_THROWS_WITH(parse_scene(s, "s.json"), Catch::Contains("loads[0].to_frame: frame 9 is after the run's last frame (5"));
  }
}

TEST_CASE("a through-cut near the clamp removes the free part, though it is the larger", "[cut][scene]") {
  // The blade crosses the beam at x = 1.03 over frames 1..3: the clamped part (a quarter of the
  // volume) is the smaller, so the cutter takes the free part for the body; the scene holds
  // the clamped one and not the free one, which it removes (static FEM) instead of solving a
  // system with a free part in it.
  const Scene s = parse_scene(
      beam_scene(R"({"blade": [[1.03, -0.5, -0.5], [1.03, -0.5, 1.5]], "sweep": [0, 2, 0], "from_frame": 1, "to_frame": 3})"),
      "scene.json");
  fs::path out;
  const SceneRunSummary sum = run_in(s, "near_clamp", out);
  CHECK(sum.fragments_handled == 1);
  CHECK(sum.frames_not_converged == 0);
  // What stays is the clamped part, x < 1.03 up to snapping (within 0.05 of the 0.5 cells).
  CHECK(frame_volume(out, "frame_0005.vtu") == Approx(1.03).margin(0.025));
}

TEST_CASE("a path cut bends where its keys say and detaches the beam's end", "[cut][scene]") {
  // A vertical blade enters the beam's side at x = 2.03 and turns towards +x halfway across:
  // keys at frames 1, 3 and 5 (placed at 1, one step a frame over 2..5, withdrawn after 5).
  const Scene s = parse_scene(beam_scene(R"({"path": [
      {"frame": 1, "blade": [[2.03, -0.5, -0.5], [2.03, -0.5, 1.5]]},
      {"frame": 3, "blade": [[2.03, 0.5, -0.5], [2.03, 0.5, 1.5]]},
      {"frame": 5, "blade": [[2.53, 1.5, -0.5], [2.53, 1.5, 1.5]]}]})"),
                              "scene.json");
  REQUIRE(s.cuts.size() == 1);
  CHECK(s.cuts[0].path.size() == 3);
  CHECK(s.cuts[0].from_frame == 2);
  CHECK(s.cuts[0].to_frame == 5);
  fs::path out;
  const SceneRunSummary sum = run_in(s, "path", out);
  CHECK(sum.fragments_handled == 1);  // the free end, removed (static FEM)
  CHECK(sum.frames_not_converged == 0);
  const double volume = frame_volume(out, "frame_0005.vtu");
  // What stays: x < 2.03 for y < 0.5, then left of the line towards (2.53, 1.5), which reaches
  // x = 2.28 at y = 1: 2.03 + 0.0625 (of 4).
  CHECK(volume == Approx(2.03 + 0.0625).epsilon(0.002));

  CHECK_THROWS_WITH(parse_scene(beam_scene(R"({"path": [{"frame": 1, "blade": [[0, 0, 0], [1, 0, 0]]}]})"), "s.json"),
                    Catch::Contains("cuts[0].path: expected an array of at least two"));
  CHECK_THROWS_WITH(
      parse_scene(beam_scene(R"({"path": [{"frame": 2, "blade": [[0, 0, 0], [1, 0, 0]]}, {"frame": 2, "blade": [[0, 1, 0], [1, 1, 0]]}]})"),
                  "s.json"),
      Catch::Contains("cuts[0].path[1].frame: expected an integer >= 3"));
  CHECK_THROWS_WITH(
      parse_scene(beam_scene(R"({"path": [{"frame": 2, "blade": [[0, 0, 0], [1, 0, 0]]}, {"frame": 6, "blade": [[0, 1, 0], [1, 1, 0]]}]})"),
                  "s.json"),
      Catch::Contains("cuts[0].path[1].frame: frame 6 is after the run's last frame"));
  CHECK_THROWS_WITH(
      parse_scene(beam_scene(R"({"path": [{"frame": 1, "blade": [[0, 0, 0], [1, 0, 0]]}, {"frame": 2, "blade": [[0, 0, 0], [1, 0, 0]]}]})"),
                  "s.json"),
      Catch::Contains("cuts[0].path: the blade never moves"));
  CHECK_THROWS_WITH(
      parse_scene(beam_scene(R"({"path": [{"frame": 1, "blade": [[0, 0, 0], [1, 0, 0]]}, {"frame": 2, "blade": [[0, 1, 0], [1, 1, 0]]}], "sweep": [0, 0, 1]})"),
                  "s.json"),
      Catch::Contains("cuts[0].sweep: not with \"path\""));
}
