// Scenes with "solver": {"backend": "petsc"}: parsed and refused with one line naming the file
// and the key, and played by the scene runner to the direct solve's displacement.
#include <catch2/catch.hpp>

#include <string>

#include "mesh/errors.h"
#include "scene/run_scene.h"
#include "scene/scene.h"
#include "sim/petsc/petsc_solver.h"

using namespace incise;

namespace {

std::string beam(const std::string& solver, const std::string& extra = "") {
  return R"({"mesh": {"generate": "box", "size": [4, 1, 1], "cells": [8, 2, 2]}, "model": "fem-corotational",
  "formulation": "nodal-averaged", "materials": {"*": {"young": 1e4, "poisson": 0.45, "density": 1}},
  "fixed": [{"box": [-0.01, -1, -1, 0.01, 2, 2]}],
  "loads": [{"type": "gravity", "g": [0, 0, -1]},
            {"type": "probe", "box": [3.99, -1, -1, 4.01, 2, 2], "displacement": [0, 0, -0.3], "from_frame": 0, "to_frame": 3}],
  "solver": )" + solver + R"(, "time": {"frames": 4})" + extra + "}";
}

std::string error_of(const std::string& text) {
  try {
    parse_scene(text, "scene.json");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("scene solver.backend: petsc parsed, wrong uses refused with one line", "[scene][petsc]") {
  CHECK_THAT(error_of(beam(R"({"backend": "hypre"})")),
             Catch::Contains("scene.json") && Catch::Contains("solver.backend") && Catch::Contains("\"hypre\""));
  CHECK_THAT(error_of(beam(R"({"petsc_options": "-ksp_type cg"})")), Catch::Contains("solver.petsc_options"));
  if (!petsc_built()) {
    CHECK_THAT(error_of(beam(R"({"backend": "petsc"})")), Catch::Contains("built without PETSc"));
    return;
  }
  CHECK_THAT(error_of(beam(R"({"backend": "petsc", "method": "direct"})")), Catch::Contains("solver.backend"));
  CHECK_THAT(error_of(beam(R"({"backend": "petsc", "operator": "assembled"})")), Catch::Contains("solver.operator"));
  std::string mixed = beam(R"({"backend": "petsc"})");
  mixed.replace(mixed.find("nodal-averaged"), 14, "mixed");
  CHECK(error_of(mixed).empty());  // MINRES and a field split, in rank 0's process
  const Scene s = parse_scene(beam(R"({"backend": "petsc", "petsc_options": "-pc_gamg_threshold 0.01"})"), "scene.json");
  CHECK(s.backend == StiffnessBackend::Petsc);
  CHECK(s.petsc_options == "-pc_gamg_threshold 0.01");
}

TEST_CASE("scene solver.backend petsc: the run equals the direct solve's", "[scene][petsc]") {
  if (!petsc_built()) return;
  auto run = [](const std::string& solver) {
    std::vector<Eigen::VectorXd> out;
    SceneRunOptions ro;
    ro.on_frame = [&](int, const Eigen::VectorXd& d, const FrameStats&) { out.push_back(d); };
    run_scene(parse_scene(beam(solver), "scene.json"), ro);
    return out;
  };
  const auto ref = run(R"({"method": "direct"})");
  const auto petsc = run(R"({"backend": "petsc", "tolerance": 1e-11})");
  REQUIRE(ref.size() == 4);
  REQUIRE(petsc.size() == 4);
  for (std::size_t f = 0; f < ref.size(); ++f) CHECK((petsc[f] - ref[f]).norm() <= 1e-8 * ref[f].norm());
}
