// incise trade: the grid runs end to end, trade.csv has the documented columns and sensible
// numbers (the reference's own setting has error 0, tighter tolerances do not get worse),
// trade.svg marks the Pareto frontier, progress goes to stderr, bad input is one line.
#include <catch2/catch.hpp>

#include <map>
#include <vector>

#include "cli_run.h"

namespace fs = std::filesystem;
using namespace incise::testing;

namespace {

const char* kTradeScene = R"({
  "mesh": {"generate": "box", "size": [4, 1, 1], "cells": [8, 2, 2]},
  "model": "fem-corotational",
  "materials": {"*": {"young": 1e5, "poisson": 0.3}},
  "fixed": [{"box": [-0.01, -0.01, -0.01, 0.01, 1.01, 1.01]}],
  "loads": [{"type": "probe", "box": [3.99, -0.01, -0.01, 4.01, 1.01, 1.01], "displacement": [0, 0, -0.8],
             "from_frame": 0, "to_frame": 3}],
  "time": {"frames": 4}
})";

std::vector<std::map<std::string, std::string>> read_csv(const std::string& text) {
  std::vector<std::map<std::string, std::string>> rows;
  std::stringstream in(text);
  std::string line;
  std::vector<std::string> header;
  auto split = [](const std::string& l) {
    std::vector<std::string> f;
    std::stringstream s(l);
    for (std::string x; std::getline(s, x, ',');) f.push_back(x);
    if (!l.empty() && l.back() == ',') f.push_back("");
    return f;
  };
  std::getline(in, line);
  header = split(line);
  while (std::getline(in, line)) {
    const auto f = split(line);
    REQUIRE(f.size() == header.size());
    std::map<std::string, std::string> r;
    for (std::size_t i = 0; i < f.size(); ++i) r[header[i]] = f[i];
    rows.push_back(r);
  }
  return rows;
}

// `incise trade DIR/scene.json -o DIR/out OPTIONS`.
std::string trade_args(const fs::path& dir, const std::string& options) {
  return "trade " + q(dir / "scene.json") + " -o " + q(dir / "out") + " " + options;
}

}  // namespace

TEST_CASE("incise trade writes the grid, the errors against a converged reference and the Pareto plot", "[cli][trade][long]") {
  const fs::path dir = scratch_dir("cli_trade");
  {
    std::ofstream(dir / "scene.json") << kTradeScene;
  }
  const Run r = run_incise("trade '" + (dir / "scene.json").string() + "' -o '" + (dir / "out").string() +
                               "' --tolerances 1e-2 1e-6 --budgets 0 --resolutions 0 1 --formulations standard nodal-averaged"
                               " --json '" + (dir / "out" / "trade.json").string() + "'",
                           dir);
  INFO("stderr: " << r.err);
  REQUIRE(r.code == 0);
  // The plan, the reference and its error bar, a progress bar, the answer.
  CHECK(r.err.find("trade: reference: level 2 (12288 tets), fem-corotational quadratic, direct") != std::string::npos);
  CHECK(r.err.find("it differs from level 1 by") != std::string::npos);
  CHECK(r.err.find("so its error bar (Richardson, order 2) is ") != std::string::npos);
  CHECK(r.err.find("trade: 38 runs; the estimate of the time left follows each") != std::string::npos);
  CHECK(r.err.find("[####################] 38/38") != std::string::npos);
  CHECK(r.err.find("; about 0 s left\n") != std::string::npos);  // after the last run
  for (const char* line : {"Pareto frontier (fastest first):", "for a 2 ms frame: ", "for a 16 ms frame: ", "for a 33 ms frame: "})
    CHECK(r.out.find(line) != std::string::npos);
  const std::string csv = slurp(dir / "out" / "trade.csv");
  REQUIRE(csv.rfind("resolution,tets,model,formulation,solver,preconditioner,tolerance,budget_ms,ms_per_frame,iterations,"
                    "error,max_displacement_error,compared,settle_frames,settle_ms,dt,settled,frames_not_converged,pareto,resolved\n",
                    0) == 0);
  const auto rows = read_csv(csv);
  // Discretization: 2 levels x (2 FEM models x 2 formulations + springs with a volume term per
  // tet and one averaged at the vertices, each with Van Gelder's and fitted constants on the
  // edges and with Van Gelder's across the faces too); solvers: 2 FEM models x (direct + 4
  // preconditioners x 2 tolerances).
  REQUIRE(rows.size() == 38);
  std::map<std::string, double> err;
  int pareto = 0;
  for (const auto& row : rows) {
    const std::string key = row.at("resolution") + " " + row.at("model") + " " + row.at("formulation") + " " + row.at("solver") +
                            " " + row.at("preconditioner") + " " + row.at("tolerance");
    err[key] = std::stod(row.at("error"));
    CHECK(std::stod(row.at("ms_per_frame")) > 0);
    CHECK(std::isfinite(std::stod(row.at("error"))));
    pareto += row.at("pareto") == "1";
    if (row.at("model") == "springs") {
      // Compared at rest, and settled: a meaningful error, not "100% wrong".
      const std::string f = row.at("formulation");
      CHECK((f == "volume tet" || f == "volume nodal" || f == "volume tet (fitted)" || f == "volume nodal (fitted)" ||
             f == "volume tet across-faces" || f == "volume nodal across-faces"));
      CHECK(row.at("compared") == "at-rest");
      CHECK(row.at("settled") == "1");
      CHECK(std::stoi(row.at("settle_frames")) > 3);
      CHECK(std::stod(row.at("error")) < 0.5);
    } else {
      CHECK(row.at("compared") == "per-frame");
    }
  }
  CHECK(pareto >= 1);
  // Tighter tolerances do not get worse; every preconditioner reaches the direct solve's answer.
  for (const char* pc : {"jacobi", "block-jacobi", "cholesky", "amg"}) {
    INFO(pc);
    const std::string tight = std::string("0 fem-corotational standard cg ") + pc + " 1e-06";
    // Where the mesh's error dominates, a loose solve may land a hair closer to the reference by
    // chance (block-jacobi at 1e-2 did against the quadratic reference): not by more than 1%.
    CHECK(err.at(tight) <= 1.01 * err.at(std::string("0 fem-corotational standard cg ") + pc + " 0.01") + 1e-9);
    CHECK(std::abs(err.at(tight) - err.at("0 fem-corotational standard direct  0")) < 1e-4);
  }
  // The finer mesh is closer to the converged reference, for each model and formulation.
  for (const char* mf : {"fem-linear standard", "fem-corotational standard", "fem-corotational nodal-averaged"}) {
    INFO(mf);
    const std::string tail = std::string(" ") + mf + " cg cholesky 1e-08";
    CHECK(err.at("1" + tail) < err.at("0" + tail));
  }
  // Large rotations: linear elements are off the corotational answer by more than the mesh is.
  CHECK(err.at("1 fem-linear standard cg cholesky 1e-08") > err.at("1 fem-corotational standard cg cholesky 1e-08"));
  const std::string svg = slurp(dir / "out" / "trade.svg");
  CHECK(svg.rfind("<svg", 0) == 0);
  CHECK(svg.find("<polyline") != std::string::npos);
  CHECK(svg.find("Pareto") != std::string::npos);
  CHECK(svg.find(">16 ms</text>") != std::string::npos);  // the frame budgets
  CHECK(svg.find("mesh level 1 (refined)") != std::string::npos);
  CHECK(svg.find("fem-corotational nodal-averaged") != std::string::npos);
  const std::string json = slurp(dir / "out" / "trade.json");
  CHECK(json.find("\"recommendations\"") != std::string::npos);
  CHECK(json.find("\"change_from_coarser\"") != std::string::npos);
  CHECK(json.find("\"error_bar\"") != std::string::npos);
}

TEST_CASE("incise trade: a finer resolution never reports a larger error on the cantilever", "[cli][trade][long]") {
  // Timoshenko's cantilever as a scene: clamped at x = 0, a tip load. The reference is two levels
  // above the scene's mesh; the coarser (-1), scene (0) and refined (1) meshes must come closer
  // to it in turn, for every formulation, at nu = 0.45 where standard tets lock.
  const fs::path dir = scratch_dir("cli_trade_cantilever");
  {
    std::ofstream(dir / "beam.json") << R"({
      "mesh": {"generate": "box", "size": [10, 1, 1], "cells": [20, 2, 2]},
      "model": "fem-linear",
      "materials": {"*": {"young": 1e6, "poisson": 0.45}},
      "fixed": [{"box": [-0.01, -0.01, -0.01, 0.01, 1.01, 1.01]}],
      "loads": [{"type": "force", "box": [9.99, -0.01, -0.01, 10.01, 1.01, 1.01], "total": [0, 0, -1]}],
      "solver": {"method": "direct"},
      "time": {"frames": 1}
    })";
  }
  const Run r = run_incise("trade '" + (dir / "beam.json").string() + "' -o '" + (dir / "out").string() +
                               "' --models fem-linear --preconditioners cholesky --tolerances 1e-8 --budgets 0 --no-direct"
                               " --resolutions -1 0 1",
                           dir);
  INFO("stderr: " << r.err);
  REQUIRE(r.code == 0);
  const auto rows = read_csv(slurp(dir / "out" / "trade.csv"));
  REQUIRE(rows.size() == 10);  // 3 levels x 3 formulations with the scene's direct solver, one CG row
  std::map<std::string, std::map<int, double>> by;
  for (const auto& row : rows)
    if (row.at("solver") == "direct") by[row.at("formulation")][std::stoi(row.at("resolution"))] = std::stod(row.at("error"));
  for (const auto& [f, e] : by) {
    INFO(f << ": " << e.at(-1) << " " << e.at(0) << " " << e.at(1));
    CHECK(e.at(0) <= e.at(-1));
    CHECK(e.at(1) <= e.at(0));
  }
  // Locking: at the scene's mesh the standard tets are further off than the other two.
  CHECK(by.at("standard").at(0) > by.at("nodal-averaged").at(0));
  CHECK(by.at("standard").at(0) > by.at("mixed").at(0));
}

TEST_CASE("incise trade: a scene whose mesh is a file gets a coarser resolution by default", "[cli][trade][long]") {
  // The cantilever again, its mesh read from a file: nothing can regenerate it coarser, so
  // level -1 is the file's mesh coarsened by edge contraction (480 -> about 60 tets); the
  // finer resolutions must not be further from the reference.
  const fs::path dir = scratch_dir("cli_trade_mesh_file");
  std::string gen = "generate box --size 10 1 1 --cells 20 2 2 -o ";
  gen += q(dir / "beam.msh");
  const Run g = run_incise(gen, dir);
  REQUIRE(g.code == 0);
  {
    std::ofstream(dir / "beam.json") << R"({
      "mesh": "beam.msh",
      "model": "fem-linear",
      "materials": {"*": {"young": 1e6, "poisson": 0.3}},
      "fixed": [{"box": [-0.01, -0.01, -0.01, 0.01, 1.01, 1.01]}],
      "loads": [{"type": "force", "box": [9.99, -0.01, -0.01, 10.01, 1.01, 1.01], "total": [0, 0, -1]}],
      "solver": {"method": "direct"},
      "time": {"frames": 1}
    })";
  }
  std::string args = "trade ";
  args += q(dir / "beam.json");
  args += " -o ";
  args += q(dir / "out");
  args += " --models fem-linear --formulations standard mixed --preconditioners cholesky --tolerances 1e-8 --budgets 0"
          " --no-direct --json ";
  args += q(dir / "out" / "trade.json");
  const Run r = run_incise(args, dir);
  INFO("stderr: " << r.err);
  REQUIRE(r.code == 0);
  CHECK(r.err.find("trade: level -1: beam.msh coarsened by edge contraction: 480 -> ") != std::string::npos);
  CHECK(r.out.find("level -1: beam.msh coarsened by edge contraction") != std::string::npos);
  CHECK(slurp(dir / "out" / "trade.json").find("\"coarser\": \"beam.msh coarsened by edge contraction") != std::string::npos);
  const auto rows = read_csv(slurp(dir / "out" / "trade.csv"));
  std::map<std::string, std::map<int, double>> by;
  std::map<int, int> tets;
  for (const auto& row : rows) {
    tets[std::stoi(row.at("resolution"))] = std::stoi(row.at("tets"));
    if (row.at("solver") == "direct") by[row.at("formulation")][std::stoi(row.at("resolution"))] = std::stod(row.at("error"));
  }
  // -1, 0 and (64 x 480 tets within the reference cap) 1.
  REQUIRE(tets.size() == 3);
  CHECK(tets.at(0) == 480);
  CHECK(tets.at(-1) * 4 <= tets.at(0));
  CHECK(tets.at(1) == 8 * 480);
  REQUIRE(by.size() == 2);
  for (const auto& [f, e] : by) {
    INFO(f << ": " << e.at(-1) << " " << e.at(0) << " " << e.at(1));
    CHECK(e.at(0) <= e.at(-1));
    CHECK(e.at(1) <= e.at(0));
  }
}

TEST_CASE("incise trade: bad input is one line, nothing written", "[cli][trade][errors]") {
  const fs::path dir = scratch_dir("cli_trade_errors");
  Run r = run_incise("trade '" + (dir / "missing.json").string() + "' -o '" + (dir / "out").string() + "'", dir);
  CHECK(r.code == 1);
  CHECK(r.err.rfind("incise: error: " + (dir / "missing.json").string(), 0) == 0);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  {
    std::ofstream(dir / "scene.json") << kTradeScene;
  }
  r = run_incise("trade '" + (dir / "scene.json").string() + "' -o '" + (dir / "out").string() + "' --preconditioners ilu", dir);
  CHECK(r.code == 1);
  CHECK(r.err.find("--preconditioners: expected \"jacobi\"") != std::string::npos);
  CHECK(!fs::exists(dir / "out" / "trade.csv"));
  r = run_incise("trade '" + (dir / "scene.json").string() + "' -o '" + (dir / "out").string() + "' --spring-stiffness lloyd", dir);
  CHECK(r.code == 1);
  CHECK(r.err.find("--spring-stiffness: expected van-gelder or fitted, got \"lloyd\"") != std::string::npos);
  r = run_incise("trade '" + (dir / "scene.json").string() + "' -o '" + (dir / "out").string() + "' --spring-connectivity rings", dir);
  CHECK(r.code == 1);
  CHECK(r.err.find("--spring-connectivity: expected edges or across-faces, got \"rings\"") != std::string::npos);
  r = run_incise("trade '" + (dir / "scene.json").string() + "' -o '" + (dir / "out").string() + "' --formulations bar", dir);
  CHECK(r.code == 1);
  CHECK(r.err.find("--formulations: expected \"standard\", \"nodal-averaged\", \"edge-smoothed\", \"mixed\", "
                   "\"mixed-edge-smoothed\", \"quadratic\" or \"mixed-quadratic\", got \"bar\"") != std::string::npos);
  r = run_incise("trade '" + (dir / "scene.json").string() + "' -o '" + (dir / "out").string() +
                     "' --resolutions 0 1 --reference-level 1",
                 dir);
  CHECK(r.code == 1);
  CHECK(r.err.find("the reference level (1) must be above the finest resolution (1)") != std::string::npos);
  CHECK(!fs::exists(dir / "out" / "trade.csv"));
}

TEST_CASE("incise trade: dynamic runs are compared at rest under the loads of the reference's last frame",
          "[cli][trade][long]") {
  // The probe ramps over 30 frames and trade compares 2 (`--frames 2`): the reference's last
  // frame has a thirtieth of it. Springs (dynamic, settled at rest) once played on past the
  // ramp, and were compared pressed the whole way (docs/solver.md, *Like with like*).
  const fs::path dir = scratch_dir("cli_trade_at_rest");
  {
    std::string scene = kTradeScene;
    scene.replace(scene.find("\"to_frame\": 3"), 13, "\"to_frame\": 30");
    scene.replace(scene.find("\"frames\": 4"), 11, "\"frames\": 40");
    std::ofstream(dir / "scene.json") << scene;
  }
  const Run r = run_incise(trade_args(dir, "--frames 2 --models springs fem-corotational --formulations standard "
                                          "--resolutions 0 --preconditioners cholesky --tolerances 1e-8 --budgets 0 "
                                          "--no-direct -q"),
                           dir);
  INFO("stderr: " << r.err);
  REQUIRE(r.code == 0);
  const auto rows = read_csv(slurp(dir / "out" / "trade.csv"));
  bool springs = false;
  for (const auto& row : rows)
    if (row.at("model") == "springs") {
      springs = true;
      INFO("springs at rest: error " << row.at("error"));
      CHECK(std::stod(row.at("error")) < 0.5);
    }
  CHECK(springs);
}

TEST_CASE("incise trade --spring-nodal-shares: a row per share of the nodal volume term", "[cli][trade][long]") {
  const fs::path dir = scratch_dir("cli_trade_shares");
  {
    std::ofstream(dir / "scene.json") << kTradeScene;
  }
  const Run r = run_incise(trade_args(dir, "--models springs --spring-volumes nodal tet --spring-stiffness van-gelder "
                                          "--spring-connectivity edges --spring-nodal-shares 1 0.5 0 --resolutions 0 "
                                          "--no-direct -q"),
                           dir);
  INFO("stderr: " << r.err);
  REQUIRE(r.code == 0);
  std::map<std::string, double> err;
  for (const auto& row : read_csv(slurp(dir / "out" / "trade.csv"))) err[row.at("formulation")] = std::stod(row.at("error"));
  REQUIRE(err.size() == 4);  // the per-tet row once, the nodal one per share
  REQUIRE(err.count("volume nodal 1"));
  REQUIRE(err.count("volume nodal 0.5"));
  REQUIRE(err.count("volume nodal 0"));
  REQUIRE(err.count("volume tet"));
  CHECK(err["volume nodal 1"] != err["volume nodal 0.5"]);
  CHECK(err["volume nodal 0"] == Approx(err["volume tet"]).epsilon(1e-3));  // share 0: the per-tet term
  const Run bad = run_incise("trade " + q(dir / "scene.json") + " -o " + q(dir / "out2") + " --spring-nodal-shares 1.5", dir);
  CHECK(bad.code == 1);
  CHECK(bad.err.find("--spring-nodal-shares: expected values in [0, 1]") != std::string::npos);
  CHECK(!fs::exists(dir / "out2" / "trade.csv"));
}

TEST_CASE("incise trade --convergence: errors per level against the quadratic reference, and the orders",
          "[cli][trade]") {
  // The 8 x 1 x 1 cantilever, 8 x 1 x 1 cells at level 0, levels 0 and 1 against a level-2 reference.
  const fs::path dir = scratch_dir("cli_trade_convergence");
  {
    std::ofstream(dir / "beam.json") << R"({
      "mesh": {"generate": "box", "size": [8, 1, 1], "cells": [8, 1, 1]},
      "model": "fem-linear",
      "materials": {"*": {"young": 1e6, "poisson": 0.3}},
      "fixed": [{"box": [-0.01, -0.01, -0.01, 0.01, 1.01, 1.01]}],
      "loads": [{"type": "traction", "box": [7.99, -0.01, -0.01, 8.01, 1.01, 1.01], "value": [0, 0, -1]}],
      "time": {"frames": 1}
    })";
  }
  const Run r = run_incise("trade " + q(dir / "beam.json") + " -o " + q(dir / "out") +
                               " --convergence --models fem-linear --formulations standard quadratic --resolutions 0 1",
                           dir);
  INFO("stderr: " << r.err << "\nstdout: " << r.out);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("convergence against a level-2 reference (3072 tets, fem-corotational quadratic, direct; error bar") !=
        std::string::npos);
  CHECK(r.out.find("p 0-1") != std::string::npos);
  const auto rows = read_csv(slurp(dir / "out" / "convergence.csv"));
  REQUIRE(rows.size() == 4);
  std::map<std::string, std::map<int, double>> err;
  for (const auto& row : rows) err[row.at("formulation")][std::stoi(row.at("level"))] = std::stod(row.at("error"));
  // Quadratic tets converge, and at each level are far closer than linear ones.
  CHECK(err.at("quadratic").at(1) < 0.5 * err.at("quadratic").at(0));
  for (int level : {0, 1}) CHECK(err.at("quadratic").at(level) < 0.3 * err.at("standard").at(level));
  const double order = std::stod(rows.at(2).at("order_to_next"));  // quadratic, level 0 -> 1
  CHECK(rows.at(2).at("formulation") == "quadratic");
  CHECK(order > 1.5);
}
