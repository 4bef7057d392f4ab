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

const char* kScene = R"({
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

}  // namespace

TEST_CASE("incise trade writes the grid, the errors and the Pareto plot", "[cli][trade]") {
  const fs::path dir = scratch_dir("cli_trade");
  {
    std::ofstream(dir / "scene.json") << kScene;
  }
  const Run r = run_incise("trade '" + (dir / "scene.json").string() + "' -o '" + (dir / "out").string() +
                               "' --tolerances 1e-2 1e-6 --budgets 0",
                           dir);
  INFO("stderr: " << r.err);
  REQUIRE(r.code == 0);
  CHECK(r.err.find("trade: reference") != std::string::npos);
  CHECK(r.err.find("trade: 20/20") != std::string::npos);
  const std::string csv = slurp(dir / "out" / "trade.csv");
  REQUIRE(csv.rfind("model,solver,preconditioner,tolerance,budget_ms,ms_per_frame,iterations,error,", 0) == 0);
  const auto rows = read_csv(csv);
  // Per FEM model: direct + 4 preconditioners x 2 tolerances; springs: 2 tolerances.
  REQUIRE(rows.size() == 20);
  std::map<std::string, double> err;
  int pareto = 0;
  for (const auto& row : rows) {
    const std::string key = row.at("model") + " " + row.at("solver") + " " + row.at("preconditioner") + " " + row.at("tolerance");
    err[key] = std::stod(row.at("error"));
    CHECK(std::stod(row.at("ms_per_frame")) > 0);
    CHECK(std::isfinite(std::stod(row.at("error"))));
    pareto += row.at("pareto") == "1";
  }
  CHECK(pareto >= 1);
  CHECK(err.at("fem-corotational direct  0") == 0);  // the reference's own setting
  for (const char* pc : {"jacobi", "block-jacobi", "cholesky", "amg"}) {
    INFO(pc);
    CHECK(err.at(std::string("fem-corotational cg ") + pc + " 1e-06") < 1e-4);
    CHECK(err.at(std::string("fem-corotational cg ") + pc + " 1e-06") <= err.at(std::string("fem-corotational cg ") + pc + " 0.01") + 1e-9);
  }
  // Large rotations: linear elements are measurably off the corotational answer.
  CHECK(err.at("fem-linear direct  0") > 1e-3);
  const std::string svg = slurp(dir / "out" / "trade.svg");
  CHECK(svg.rfind("<svg", 0) == 0);
  CHECK(svg.find("<polyline") != std::string::npos);
  CHECK(svg.find("Pareto") != std::string::npos);
}

TEST_CASE("incise trade: bad input is one line, nothing written", "[cli][trade][errors]") {
  const fs::path dir = scratch_dir("cli_trade_errors");
  Run r = run_incise("trade '" + (dir / "missing.json").string() + "' -o '" + (dir / "out").string() + "'", dir);
  CHECK(r.code == 1);
  CHECK(r.err.rfind("incise: error: " + (dir / "missing.json").string(), 0) == 0);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  {
    std::ofstream(dir / "scene.json") << kScene;
  }
  r = run_incise("trade '" + (dir / "scene.json").string() + "' -o '" + (dir / "out").string() + "' --preconditioners ilu", dir);
  CHECK(r.code == 1);
  CHECK(r.err.find("--preconditioners: expected \"jacobi\"") != std::string::npos);
  CHECK(!fs::exists(dir / "out" / "trade.csv"));
}
