// incise quality: the JSON report of a generated mesh, options, and one-line errors.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "cli_run.h"

namespace fs = std::filesystem;

using incise::testing::Run;
using incise::testing::run_incise;
using incise::testing::scratch_dir;
using incise::testing::slurp;

TEST_CASE("incise quality --json on a generated box", "[cli][quality]") {
  const fs::path dir = scratch_dir("cli_quality");
  const std::string mesh = (dir / "box.vtu").string();
  Run gen = run_incise("generate box --size 2 1 1 --cells 4 2 2 --label 7 -o '" + mesh + "'", dir);
  REQUIRE(gen.code == 0);

  Run q = run_incise("quality '" + mesh + "' --json --worst 5 --metric radius_ratio --histogram-bins 6", dir);
  INFO(q.err);
  REQUIRE(q.code == 0);
  const nlohmann::json j = nlohmann::json::parse(q.out);
  CHECK(j["schema"] == "incise.quality/1");
  CHECK(j["file"] == mesh);
  const std::size_t tets = 6 * 4 * 2 * 2;
  CHECK(j["counts"]["tets"] == tets);
  CHECK(j["counts"]["vertices"] == 5 * 3 * 3);
  CHECK(j["counts"]["boundary_faces"] == 2 * 2 * (8 + 8 + 4));
  CHECK(j["volume"].get<double>() == Approx(2).epsilon(1e-12));
  CHECK(j["bounding_box"]["max"][0].get<double>() == Approx(2));
  CHECK(j["elements"]["inverted"] == 0);
  CHECK(j["elements"]["degenerate"] == 0);
  CHECK(j["elements"]["slivers"] == 0);
  CHECK(j["components"] == 1);
  CHECK(j["boundary"]["closed"] == true);
  CHECK(j["boundary"]["manifold"] == true);
  CHECK(j["boundary"]["shells"] == 1);
  CHECK(j["boundary"]["non_manifold_edges"] == 0);
  // Every tet is a Kuhn tet.
  const auto& m = j["metrics"];
  CHECK(m["min_dihedral"]["min"].get<double>() == Approx(45).epsilon(1e-12));
  CHECK(m["max_dihedral"]["max"].get<double>() == Approx(90).epsilon(1e-12));
  CHECK(m["radius_ratio"]["percentiles"]["p50"].get<double>() == Approx(0.717439).margin(1e-6));
  CHECK(m["mean_ratio"]["mean"].get<double>() == Approx(0.755953).margin(1e-6));
  CHECK(m["volume_length"]["max"].get<double>() == Approx(0.657267).margin(1e-6));
  for (const char* name : {"volume", "min_dihedral", "max_dihedral", "radius_ratio", "mean_ratio", "volume_length",
                           "aspect_ratio", "min_solid_angle", "radius_edge"}) {
    INFO(name);
    REQUIRE(m.contains(name));
    CHECK(m[name]["count"] == tets);
    CHECK(m[name]["histogram"]["counts"].size() == 6);
    std::size_t total = m[name]["histogram"]["below"].get<std::size_t>() + m[name]["histogram"]["above"].get<std::size_t>();
    for (const auto& c : m[name]["histogram"]["counts"]) total += c.get<std::size_t>();
    CHECK(total == tets);
  }
  CHECK(j["worst"]["metric"] == "radius_ratio");
  REQUIRE(j["worst"]["elements"].size() == 5);
  CHECK(j["worst"]["elements"][0]["label"] == 7);
  CHECK(j["worst"]["elements"][0]["radius_ratio"].get<double>() == Approx(0.717439).margin(1e-6));
  REQUIRE(j["labels"].size() == 1);
  CHECK(j["labels"][0]["label"] == 7);
  CHECK(j["labels"][0]["tets"] == tets);
  CHECK(j["solver"]["available"] == true);
  CHECK(j["solver"]["kappa"].get<double>() > j["solver"]["kappa_laplace"].get<double>());
  CHECK(j["solver"]["cg_iterations"].get<double>() > 1);
  CHECK(j["solver"]["source"] == "formula");
  // The measured estimate (a short CG solve; this box is small enough to converge within it).
  const auto& me = j["solver"]["measured"];
  REQUIRE(me.is_object());
  CHECK(me["available"] == true);
  CHECK(me["source"] == "measured: Lanczos from 100 CG iterations");
  CHECK(me["clamp_axis"] == "x");
  CHECK(me["fixed_vertices"] == 3 * 3);
  for (const char* pc : {"none", "jacobi"}) {
    INFO(pc);
    CHECK(me[pc]["cg_iterations"].get<double>() >= 1);
    CHECK(me[pc]["kappa"].get<double>() > 1);
    CHECK(me[pc]["lambda_max"].get<double>() > me[pc]["lambda_min"].get<double>());
  }
  CHECK(j["options"]["histogram_bins"] == 6);

  // --solver-estimate formula skips the solve; --lanczos-iterations says how short it is.
  Run f = run_incise("quality '" + mesh + "' --json --solver-estimate formula", dir);
  REQUIRE(f.code == 0);
  CHECK_FALSE(nlohmann::json::parse(f.out)["solver"].contains("measured"));
  Run l = run_incise("quality '" + mesh + "' --json --lanczos-iterations 5", dir);
  REQUIRE(l.code == 0);
  const nlohmann::json lj = nlohmann::json::parse(l.out)["solver"]["measured"];
  CHECK(lj["source"] == "measured: Lanczos from 5 CG iterations");
  CHECK(lj["none"]["iterations_run"] == 5);
  CHECK(lj["none"]["converged"] == false);
  Run text = run_incise("quality '" + mesh + "'", dir);
  REQUIRE(text.code == 0);
  CHECK(text.out.find("solver (formula): condition number") != std::string::npos);
  CHECK(text.out.find("solver (measured: Lanczos from 100 CG iterations") != std::string::npos);
  CHECK(run_incise("quality '" + mesh + "' --solver-estimate guess", dir).code != 0);

  // The sliver threshold follows the option.
  Run s = run_incise("quality '" + mesh + "' --json --sliver-angle 50", dir);
  REQUIRE(s.code == 0);
  CHECK(nlohmann::json::parse(s.out)["elements"]["slivers"] == tets);

  // Text output for people.
  Run t = run_incise("quality '" + mesh + "'", dir);
  REQUIRE(t.code == 0);
  CHECK_THAT(t.out, Catch::Contains("1 component"));
  CHECK_THAT(t.out, Catch::Contains("closed, manifold"));
  CHECK_THAT(t.out, Catch::Contains("worst 10 by mean_ratio"));
  fs::remove_all(dir);
}

TEST_CASE("incise quality fails with one line on bad input", "[cli][quality]") {
  const fs::path dir = scratch_dir("cli_quality_errors");
  auto one_line = [](const std::string& s) { return !s.empty() && s.find('\n') == s.size() - 1; };

  Run missing = run_incise("quality '" + (dir / "no_such_mesh.vtu").string() + "'", dir);
  CHECK(missing.code == 1);
  CHECK(one_line(missing.err));
  CHECK_THAT(missing.err, Catch::Contains("no_such_mesh.vtu"));
  CHECK(missing.out.empty());

  const std::string mesh = (dir / "box.msh").string();
  REQUIRE(run_incise("generate box --cells 2 2 2 -o '" + mesh + "'", dir).code == 0);
  Run metric = run_incise("quality '" + mesh + "' --metric ugliness", dir);
  CHECK(metric.code == 1);
  CHECK(one_line(metric.err));
  CHECK_THAT(metric.err, Catch::Contains("mean_ratio"));

  Run bins = run_incise("quality '" + mesh + "' --histogram-bins 0", dir);
  CHECK(bins.code == 1);
  CHECK(one_line(bins.err));

  std::ofstream(dir / "garbage.vtu") << "this is not a mesh\n";
  Run garbage = run_incise("quality '" + (dir / "garbage.vtu").string() + "'", dir);
  CHECK(garbage.code == 1);
  CHECK(one_line(garbage.err));
  fs::remove_all(dir);
}
