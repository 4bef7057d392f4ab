// Scenes: every bad key is named with what was expected, nothing is written on bad input,
// and a scene runs end to end into VTU frames, a .pvd series and stats.csv.
#include <catch2/catch.hpp>

#include <filesystem>
#include <cmath>
#include <fstream>
#include <unistd.h>
#include <sstream>

#include "mesh/errors.h"
#include "mesh/io/tet_io.h"
#include "scene/run_scene.h"
#include "sim/springs/spring_model.h"

using namespace incise;
namespace fs = std::filesystem;

namespace {

const char* kGood = R"({
  "mesh": {"generate": "box", "size": [4, 1, 1], "cells": [8, 2, 2]},
  "model": "fem-linear",
  "materials": {"*": {"young": 1e5, "poisson": 0.3, "density": 1000}},
  "fixed": [{"box": [0, 0, 0, 0, 1, 1]}],
  "loads": [{"type": "probe", "box": [4, 0, 0, 4, 1, 1], "displacement": [0, 0, -0.2], "from_frame": 0, "to_frame": 4}, {"type": "gravity", "g": [0, 0, -9.81]}],
  "solver": {"method": "cg", "tolerance": 1e-9, "max_iterations": 5000, "budget_ms": 0, "warm_start": true, "preconditioner": "jacobi"},
  "time": {"frames": 6}
})";

// kGood with one top-level key (each sits on one line) replaced by `value` (a JSON text).
std::string with(const std::string& key, const std::string& value) {
  std::string s = kGood;
  const std::string tag = "\"" + key + "\": ";
  const auto p = s.find(tag);
  REQUIRE(p != std::string::npos);
  // Replace up to the end of that value: the next top-level line break.
  const auto e = s.find(",\n", p);
  return s.substr(0, p) + tag + value + (e == std::string::npos ? "\n}" : s.substr(e));
}

std::string error_of(const std::string& text) {
  try {
    parse_scene(text, "scene.json");
  } catch (const IoError& e) {
    return e.what();
  }
  return "(no error)";
}

fs::path temp_dir(const std::string& name) {
  fs::path p = fs::temp_directory_path() / ("incise_test_scene_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(p);
  return p;
}

}  // namespace

TEST_CASE("scene errors name the key and what was expected", "[scene][errors]") {
  CHECK(error_of(kGood) == "(no error)");
  CHECK(error_of(with("solver", R"({"tolerance": -1})")) == "scene.json: solver.tolerance: expected a positive number");
  CHECK(error_of(with("solver", R"({"tolerance": "small"})")) == "scene.json: solver.tolerance: expected a positive number");
  CHECK(error_of(with("solver", R"({"tolerance": 2})")) == "scene.json: solver.tolerance: expected a relative residual in (0, 1)");
  CHECK(error_of(with("solver", R"({"tolerance": 1})")) == "scene.json: solver.tolerance: expected a relative residual in (0, 1)");
  CHECK(error_of(with("solver", R"({"max_iterations": 0})")) == "scene.json: solver.max_iterations: expected an integer >= 1");
  CHECK(error_of(with("solver", R"({"budget_ms": -5})")) == "scene.json: solver.budget_ms: expected a number >= 0");
  CHECK_THAT(error_of(with("solver", R"({"method": "lu"})")), Catch::StartsWith("scene.json: solver.method: expected \"cg\" or \"direct\""));
  CHECK_THAT(error_of(with("solver", R"({"tolerence": 1e-6})")), Catch::StartsWith("scene.json: solver.tolerence: unknown key"));
  CHECK_THAT(error_of(with("solver", R"({"preconditioner": "ilu"})")), Catch::Contains("solver.preconditioner: expected \"jacobi\", \"block-jacobi\", \"cholesky\", \"amg\" or \"none\", got \"ilu\""));
  CHECK_THAT(error_of(with("solver", R"({"warm_start": "guess"})")), Catch::Contains("solver.warm_start: expected true, false, \"predict\" or \"last\""));
  CHECK_THAT(error_of(with("model", R"("fem")")), Catch::StartsWith("scene.json: model: expected \"fem-linear\""));
  CHECK_THAT(error_of(with("materials", R"({"*": {"poisson": 0.5}})")), Catch::Contains("materials.*.poisson: Poisson's ratio 0.5 needs \"formulation\": \"mixed\""));
  CHECK_THAT(error_of(with("materials", R"({"*": {"poisson": 0.49995}})")), Catch::Contains("materials.*.poisson: Poisson's ratio 0.49995000000000001 needs \"formulation\": \"mixed\""));
  CHECK_THAT(error_of(with("materials", R"({"*": {"poisson": 0.4999999999999999}})")), Catch::Contains("the other formulations take at most 0.4999"));
  CHECK_THAT(error_of(with("materials", R"({"liver": {"young": 1}})")), Catch::Contains("materials.liver: expected \"*\" or an integer"));
  CHECK_THAT(error_of(with("materials", R"({"3": {"young": 0}})")), Catch::Contains("materials.3.young: expected a positive number"));
  CHECK_THAT(error_of(with("fixed", R"([{"box": [0, 0, 0, 1, 1]}])")), Catch::Contains("fixed[0].box: expected [xmin, ymin, zmin, xmax, ymax, zmax]"));
  CHECK_THAT(error_of(with("fixed", R"([{"box": [1, 0, 0, 0, 1, 1]}])")), Catch::Contains("fixed[0].box: expected min <= max"));
  CHECK_THAT(error_of(with("loads", R"([{"type": "push"}])")), Catch::Contains("loads[0].type: expected \"force\", \"gravity\", \"probe\", \"pressure\" or \"traction\""));
  CHECK_THAT(error_of(with("loads", R"([{"type": "force", "box": [0,0,0,1,1,1]}])")), Catch::Contains("loads[0].total: missing"));
  CHECK_THAT(error_of(with("loads", R"([{"type": "gravity", "g": [0, 0]}])")), Catch::Contains("loads[0].g: expected an array of 3 numbers"));
  CHECK_THAT(error_of(with("loads", R"([{"type": "probe", "box": [0,0,0,1,1,1], "displacement": [0,0,1], "from_frame": 5, "to_frame": 2}])")),
             Catch::Contains("loads[0].to_frame: expected an integer >= from_frame"));
  CHECK_THAT(error_of(with("time", R"({"frames": 0})")), Catch::Contains("time.frames: expected an integer >= 1"));
  CHECK_THAT(error_of(with("time", R"({"integrator": "verlet"})")), Catch::Contains("time.integrator: expected \"static\" or \"implicit-euler\""));
  CHECK_THAT(error_of(with("mesh", R"({"generate": "torus"})")), Catch::Contains("mesh.generate: expected \"box\", \"ellipsoid\", \"tube\" or \"cook\""));
  CHECK_THAT(error_of(with("mesh", "42")), Catch::Contains("mesh: expected a mesh file name"));
  CHECK_THAT(error_of(std::string(kGood) + "x"), Catch::StartsWith("scene.json:9: invalid JSON"));
  CHECK_THAT(error_of("{\n \"mesh\": \"a.vtu\",\n \"oops\": 1}"), Catch::Contains("scene.json: oops: unknown key"));
  CHECK_THAT(error_of("[1, 2]"), Catch::Contains("expected an object"));
  // Comments (as in the documentation) are accepted.
  CHECK(error_of("{ // a comment\n \"mesh\": \"a.vtu\" }") == "(no error)");
}

TEST_CASE("bad scene content is refused before anything is written", "[scene][errors]") {
  const fs::path out = temp_dir("bad");
  SceneRunOptions ro;
  ro.out_dir = out.string();
  // A box outside the mesh.
  Scene s = parse_scene(with("fixed", R"([{"box": [10, 10, 10, 11, 11, 11]}])"), "scene.json");
  CHECK_THROWS_WITH(run_scene(s, ro), Catch::Contains("scene.json: fixed[0].box: selects no vertex; the mesh spans"));
  // Under-constrained static scene.
  s = parse_scene(with("fixed", "[]"), "scene.json");
  s.loads.erase(s.loads.begin());  // no probe either
  CHECK_THROWS_WITH(run_scene(s, ro), Catch::Contains("scene.json: fixed: static solve is under-constrained"));
  // A missing mesh file is named.
  s = parse_scene(with("mesh", R"("no_such_mesh.vtu")"), "/tmp/x/scene.json");
  CHECK_THROWS_WITH(run_scene(s, ro), Catch::Contains("no_such_mesh.vtu"));
  // A material for a label no tet has (the generated box's tets all have label 1).
  s = parse_scene(with("materials", R"({"7": {"young": 2e4}})"), "scene.json");
  CHECK_THROWS_WITH(run_scene(s, ro), Catch::Contains("scene.json: materials.7: no tet of the mesh has label 7 (its labels: 1)"));
  CHECK_FALSE(fs::exists(out));
}

TEST_CASE("a scene runs end to end: frames, series and stats", "[scene]") {
  const fs::path out = temp_dir("good");
  SceneRunOptions ro;
  ro.out_dir = out.string();
  const Scene s = parse_scene(kGood, "scene.json");
  const SceneRunSummary sum = run_scene(s, ro);
  CHECK(sum.frames == 6);
  CHECK(sum.frames_not_converged == 0);
  for (int f = 0; f < 6; ++f) CHECK(fs::exists(out / ("frame_000" + std::to_string(f) + ".vtu")));
  REQUIRE(fs::exists(out / "frames.pvd"));
  REQUIRE(fs::exists(out / "stats.csv"));
  std::ifstream csv(out / "stats.csv");
  std::string header;
  std::getline(csv, header);
  CHECK_THAT(header, Catch::StartsWith("frame,time,iterations,relative_residual,solve_ms,budget_exhausted"));
  int rows = 0;
  for (std::string line; std::getline(csv, line);) ++rows;
  CHECK(rows == 6);
  // The last frame's points are current positions: the probed face (x = 4) moved by -0.2 in z,
  // so its z values are the lattice values {0, 0.5, 1} shifted by -0.2.
  const TetMesh frame = read_tet_mesh((out / "frame_0005.vtu").string());
  int n = 0;
  for (VertexId v : frame.vertices())
    if (std::abs(frame.rest(v).x() - 4) < 1e-12) {
      const double z = frame.rest(v).z() + 0.2;
      CHECK(std::abs(z - std::round(2 * z) / 2) < 1e-12);
      ++n;
    }
  CHECK(n == 9);
  CHECK(sum.max_displacement >= 0.2 - 1e-9);
  fs::remove_all(out);
}

TEST_CASE("dynamic FEM, springs and budgeted scenes run", "[scene]") {
  const fs::path out = temp_dir("dyn");
  SceneRunOptions ro;
  ro.out_dir = out.string();
  Scene s = parse_scene(with("time", R"({"frames": 5, "dt": 0.01, "integrator": "implicit-euler", "damping": 1})"), "scene.json");
  SceneRunSummary sum = run_scene(s, ro);
  CHECK(sum.frames == 5);
  CHECK(sum.frames_not_converged == 0);

  s = parse_scene(with("model", R"("springs")"), "scene.json");
  s.integrator = "implicit-euler";
  s.frames = 3;
  sum = run_scene(s, ro);
  CHECK(sum.frames == 3);
  CHECK(std::isfinite(sum.max_displacement));

  s = parse_scene(with("solver", R"({"budget_ms": 0.001, "tolerance": 1e-12, "preconditioner": "jacobi"})"), "scene.json");
  s.frames = 3;
  sum = run_scene(s, SceneRunOptions{});
  CHECK(sum.frames_budget_exhausted == 3);

  s = parse_scene(with("solver", R"({"method": "direct"})"), "scene.json");
  s.model = SceneModel::FemCorotational;
  sum = run_scene(s, SceneRunOptions{});
  CHECK(sum.frames_not_converged == 0);
  fs::remove_all(out);
}

TEST_CASE("the bundled sample scene parses and runs", "[scene]") {
  const std::string path = std::string(INCISE_SOURCE_DIR) + "/samples/scenes/beam.json";
  const Scene s = load_scene(path);
  SceneRunOptions ro;
  ro.frames = 2;
  const SceneRunSummary sum = run_scene(s, ro);
  CHECK(sum.frames == 2);
  CHECK(sum.tets > 1000);
  CHECK(sum.max_displacement > 0);
}

TEST_CASE("the swinging-liver bench scene parses, and its blade cuts the falling liver", "[scene]") {
  // bench/scenes/liver_swing_cut.json (docs/cut.md#moving-tissue): its first 20 frames (the
  // blade starts beside the body at frame 5 and reaches it at about frame 12).
  const Scene s = load_scene(std::string(INCISE_SOURCE_DIR) + "/bench/scenes/liver_swing_cut.json");
  REQUIRE(s.cuts.size() == 1);
  SceneRunOptions ro;
  ro.frames = 20;
  const SceneRunSummary sum = run_scene(s, ro);
  CHECK(sum.frames == 20);
  CHECK(sum.tets > 5332);  // the sample liver's, before the cut
  CHECK(sum.max_displacement > 10);  // it fell
}

TEST_CASE("a run whose frames are not interactive says so and names incise trade", "[scene]") {
  const Scene s = parse_scene(kGood, "scene.json");
  SceneRunOptions ro;
  CHECK(run_scene(s, ro).warnings.empty());  // a small beam: well under slow_frame_ms a frame
  ro.slow_frame_ms = 1e-9;                   // any frame is "slow"
  const SceneRunSummary sum = run_scene(s, ro);
  REQUIRE(sum.warnings.size() == 1);
  CHECK_THAT(sum.warnings[0], Catch::Contains("(median): not interactive; `incise trade scene.json` measures the settings"));
}

TEST_CASE("units: a scene that states its units gets their ranges checked, each value by its key", "[scene]") {
  auto scene = [](const std::string& units, double size, const std::string& material, double g) {
    const std::string sz = std::to_string(size);
    return parse_scene(R"({"units": ")" + units + R"(", "mesh": {"generate": "box", "size": [)" + sz + "," + sz + "," + sz +
                           R"(], "cells": [2, 2, 2]}, "model": "fem-linear", "materials": {"*": )" + material +
                           R"(}, "fixed": [{"box": [-1, -1, -1, )" +
                           std::to_string(size + 1) + R"(, 1e-3, )" + std::to_string(size + 1) +
                           R"(]}], "loads": [{"type": "gravity", "g": [0, 0, )" + std::to_string(-g) +
                           R"(]}], "time": {"frames": 1}})",
                       "scene.json");
  };
  SceneRunOptions ro;
  // Millimetres, stated, with SI numbers for the default material and g: each is named.
  const SceneRunSummary mixed = run_scene(scene("mm", 200, R"({"young": 3e6, "poisson": 0.3, "density": 1000})", 9.81), ro);
  std::string all;
  for (const std::string& w : mixed.warnings) all += w + "\n";
  INFO(all);
  CHECK_THAT(all, Catch::Contains("units \"mm\": materials[\"*\"].young is 3e+06 MPa, outside 1e-05..100000 MPa"));
  CHECK_THAT(all, Catch::Contains("units \"mm\": materials[\"*\"].density is 1000 t/mm^3"));
  CHECK_THAT(all, Catch::Contains("units \"mm\": gravity's g is 9.81 mm/s^2"));
  CHECK_THAT(all, Catch::Contains("is it in SI (m, Pa, kg/m^3, m/s^2)?"));
  CHECK(all.find("the body's size") == std::string::npos);
  // The same in one system: nothing said. Metres stated on a 200-unit mesh: the body is named.
  CHECK(run_scene(scene("mm", 200, R"({"young": 0.003, "poisson": 0.3, "density": 1e-9})", 9810), ro).warnings.empty());
  const SceneRunSummary metres = run_scene(scene("m", 200, R"({"young": 3000, "poisson": 0.3, "density": 1000})", 9.81), ro);
  REQUIRE_FALSE(metres.warnings.empty());
  CHECK_THAT(metres.warnings[0], Catch::Contains("units \"m\": the body's size (the mesh's largest extent) is 200 m"));
  CHECK(run_scene(scene("m", 0.2, R"({"young": 3000, "poisson": 0.3, "density": 1000})", 9.81), ro).warnings.empty());
  CHECK_THROWS_WITH(scene("cm", 1, R"({"young": 1})", 9.81),
                    Catch::Contains("units: expected \"mm\" (mm, MPa, t/mm^3, mm/s^2) or \"m\""));
}

TEST_CASE("units: SI materials on a body in millimetres are flagged by the sag they imply", "[scene]") {
  // Issue 39 item 4: a 200 mm body with E = 3 kPa and 1000 kg/m^3 as numbers, g = 9.81: rho g L^2
  // / E = 1.3e5, 654 times the body. In one system (mm, MPa, t/mm^3, mm/s^2) nothing is said.
  auto scene = [](const std::string& material, double g) {
    return parse_scene(R"({"mesh": {"generate": "box", "size": [200, 100, 100], "cells": [4, 2, 2]}, "model": "fem-linear",
      "materials": {"*": )" + material + R"(}, "fixed": [{"box": [-1, -1, -1, 1, 101, 101]}],
      "loads": [{"type": "gravity", "g": [0, 0, )" + std::to_string(-g) + R"(]}], "time": {"frames": 1}})",
                       "scene.json");
  };
  SceneRunOptions ro;
  // The static solve blows up (the sag is 654 bodies): the error carries the reason.
  CHECK_THROWS_WITH(run_scene(scene(R"({"young": 3000, "poisson": 0.3, "density": 1000})", 9.81), ro),
                    Catch::Contains("the solution blew up") &&
                        Catch::Contains("times the body's size: are the mesh, the moduli, the densities and g in one unit system?"));
  // Stiff enough not to blow up (a sag of 98 bodies), the run finishes and warns.
  const SceneRunSummary mixed = run_scene(scene(R"({"young": 2e4, "poisson": 0.3, "density": 1000})", 9.81), ro);
  REQUIRE(mixed.warnings.size() == 1);
  CHECK_THAT(mixed.warnings[0], Catch::Contains("implies a sag of the order of"));
  CHECK(run_scene(scene(R"({"young": 0.003, "poisson": 0.3, "density": 1e-9})", 9810), ro).warnings.empty());
}

TEST_CASE("springs.volume: per tet, averaged at the vertices, or none, bad values named", "[scene]") {
  std::string text = kGood;
  text.replace(text.find("\"fem-linear\""), 12, "\"springs\"");
  text.replace(text.find("\"time\": {\"frames\": 6}"), 21,
               R"("time": {"frames": 6, "dt": 0.01, "integrator": "implicit-euler", "damping": 5})");
  auto volume = [&](const std::string& v) {
    std::string t = text;
    t.insert(t.rfind('}'), ", \"springs\": {\"volume\": \"" + v + "\"}");
    return t;
  };
  // The displacement's norm after the run: finite and nonzero.
  auto run_norm = [](const Scene& s) {
    SceneRunOptions ro;
    double norm = 0;
    ro.on_frame = [&](int, const Eigen::VectorXd& d, const FrameStats&) { norm = d.norm(); };
    run_scene(s, ro);
    CHECK(std::isfinite(norm));
    CHECK(norm > 0);
    return norm;
  };
  // The scene's defaults are SpringOptions'.
  const Scene plain = parse_scene(text, "scene.json");
  CHECK(plain.springs_volume == (SpringOptions{}.nodal_volume ? "nodal" : "tet"));
  CHECK(plain.springs_nodal_share == SpringOptions{}.nodal_share);
  CHECK(plain.springs_inversion_guard == SpringOptions{}.inversion_guard);
  CHECK(plain.springs_connectivity == (SpringOptions{}.across_faces ? "across-faces" : "edges"));
  CHECK(plain.springs_volume == "nodal");
  double last = -1;
  for (const char* v : {"tet", "nodal", "none"}) {
    const Scene s = parse_scene(volume(v), "scene.json");
    CHECK(s.springs_volume == v);
    const double norm = run_norm(s);
    INFO(v << ": |u| " << norm);
    CHECK(norm != last);  // each is its own model
    last = norm;
  }
  CHECK(error_of(volume("edge")) == "scene.json: springs.volume: expected \"tet\", \"nodal\" or \"none\", got \"edge\"");
  // The springs' constants: Van Gelder's rule (default) or fitted per tet (docs/solver.md#spring-stiffness).
  auto stiffness = [&](const std::string& k) {
    std::string t = text;
    t.insert(t.rfind('}'), ", \"springs\": {\"stiffness\": \"" + k + "\"}");
    return t;
  };
  CHECK(parse_scene(text, "scene.json").springs_stiffness == "van-gelder");
  std::vector<double> norms;
  for (const char* k : {"van-gelder", "fitted"}) {
    const Scene s = parse_scene(stiffness(k), "scene.json");
    CHECK(s.springs_stiffness == k);
    norms.push_back(run_norm(s));
  }
  CHECK(norms[0] != norms[1]);
  CHECK(error_of(stiffness("lloyd")) == "scene.json: springs.stiffness: expected \"van-gelder\" or \"fitted\", got \"lloyd\"");
  // Connectivity: edges (default) or a spring across every interior face too (docs/solver.md#spring-connectivity).
  auto connectivity = [&](const std::string& c) {
    std::string t = text;
    t.insert(t.rfind('}'), ", \"springs\": {\"connectivity\": \"" + c + "\"}");
    return t;
  };
  CHECK(parse_scene(text, "scene.json").springs_connectivity == "across-faces");
  const Scene faces = parse_scene(connectivity("edges"), "scene.json");
  CHECK(faces.springs_connectivity == "edges");
  CHECK(run_norm(faces) != norms[0]);
  // Fitted constants are per edge: their default connectivity is edges.
  CHECK(parse_scene(stiffness("fitted"), "scene.json").springs_connectivity == "edges");
  CHECK(error_of(connectivity("second-ring")) ==
        "scene.json: springs.connectivity: expected \"edges\" or \"across-faces\", got \"second-ring\"");
  // The nodal volume term's share of the bulk modulus (the rest per tet).
  std::string blend = text;
  blend.insert(blend.rfind('}'), R"(, "springs": {"volume": "nodal", "nodal_share": 0.5})");
  const Scene bs = parse_scene(blend, "scene.json");
  CHECK(bs.springs_nodal_share == 0.5);
  CHECK(run_norm(bs) != run_norm(parse_scene(volume("nodal"), "scene.json")));
  std::string bad_share = text;
  bad_share.insert(bad_share.rfind('}'), R"(, "springs": {"nodal_share": 1.5})");
  CHECK(error_of(bad_share) == "scene.json: springs.nodal_share: expected a value in [0, 1]");
  std::string stray_share = text;
  stray_share.insert(stray_share.rfind('}'), R"(, "springs": {"volume": "tet", "nodal_share": 0.5})");
  CHECK(error_of(stray_share) == "scene.json: springs.nodal_share: is the nodal volume term's share; \"volume\" is \"tet\"");
  // The inversion guard's volume ratio.
  std::string guarded = text;
  guarded.insert(guarded.rfind('}'), R"(, "springs": {"inversion_guard": 0.3})");
  CHECK(parse_scene(guarded, "scene.json").springs_inversion_guard == 0.3);
  std::string bad_guard = text;
  bad_guard.insert(bad_guard.rfind('}'), R"(, "springs": {"inversion_guard": 1})");
  CHECK(error_of(bad_guard) == "scene.json: springs.inversion_guard: expected a volume ratio in [0, 1)");
  std::string unguarded = text;
  unguarded.insert(unguarded.rfind('}'), R"(, "springs": {"volume": "none", "inversion_guard": 0.3})");
  CHECK(error_of(unguarded) == "scene.json: springs.inversion_guard: acts beside a volume term; \"volume\" is \"none\"");
  // Kelvin-Voigt viscosity and strain-stiffening ride in the same key.
  std::string viscous = text;
  viscous.insert(viscous.rfind('}'), R"(, "springs": {"viscosity": 0.002, "stiffening": 5})");
  const Scene vs = parse_scene(viscous, "scene.json");
  CHECK(vs.springs_viscosity == 0.002);
  CHECK(vs.springs_stiffening == 5);
  SceneRunOptions ro;
  CHECK(std::isfinite(run_scene(vs, ro).max_displacement));
  std::string bad = text;
  bad.insert(bad.rfind('}'), R"(, "springs": {"stiffening": 500})");
  CHECK(error_of(bad) == "scene.json: springs.stiffening: expected a value in [0, 100]");
  // Per material too (docs/solver.md#spring-options).
  std::string per_label = text;
  per_label.replace(per_label.find("\"density\": 1000}"), 16, "\"density\": 1000, \"viscosity\": 0.002, \"stiffening\": 3}");
  const Scene pl = parse_scene(per_label, "scene.json");
  CHECK(pl.materials.fallback().viscosity == 0.002);
  CHECK(pl.materials.fallback().stiffening == 3);
  CHECK(std::isfinite(run_scene(pl, ro).max_displacement));
  std::string bad_label = text;
  bad_label.replace(bad_label.find("\"density\": 1000}"), 16, "\"density\": 1000, \"viscosity\": -1}");
  CHECK(error_of(bad_label) == "scene.json: materials.*.viscosity: expected a number >= 0");
}

TEST_CASE("springs: the stable explicit step is reported every frame, and a cut lowers it", "[scene]") {
  // A spring bar cut through the middle over frames 2-4: stats.csv's stable_dt and the
  // summary's first and smallest bound; the cut's small tets make the bound smaller.
  std::string text = kGood;
  text.replace(text.find("\"fem-linear\""), 12, "\"springs\"");
  text.replace(text.find("\"time\": {\"frames\": 6}"), 21,
               R"("time": {"frames": 6, "dt": 0.001, "integrator": "implicit-euler", "damping": 5})");
  text.insert(text.rfind('}'), R"(, "cuts": [{"blade": [[2.03, -0.5, 1.1], [2.03, 1.5, 1.1]], "sweep": [0, 0, -0.6], "from_frame": 2, "to_frame": 4}])");
  const fs::path dir = temp_dir("stable_dt");
  SceneRunOptions ro;
  ro.out_dir = dir.string();
  const SceneRunSummary r = run_scene(parse_scene(text, "scene.json"), ro);
  CHECK(r.first_stable_dt > 0);
  CHECK(r.min_stable_dt < r.first_stable_dt);
  // The estimate from the last frame's fastest mode: Gershgorin's bound is loose, never tighter
  // at a state this close to rest.
  INFO("estimated " << r.estimated_stable_dt << " s, bound at rest " << r.min_stable_dt << " s");
  CHECK(r.estimated_stable_dt >= 0.95 * r.min_stable_dt);
  CHECK(r.estimated_stable_dt < 5 * r.min_stable_dt);
  std::ifstream csv(dir / "stats.csv");
  std::string header;
  std::getline(csv, header);
  CHECK(header.find(",stable_dt") != std::string::npos);
  fs::remove_all(dir);
}
