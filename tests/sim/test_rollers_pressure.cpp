// Rollers (per-axis constraints) and pressure loads, through scenes: the uniaxial-stress patch
// held only by symmetry rollers is reproduced exactly, a roller set that leaves a rigid motion
// free is refused, and the plane-strain Lame cylinder (a quarter tube on rollers under internal
// pressure) matches the closed-form radial displacement.
#include <catch2/catch.hpp>

#include <cmath>
#include <sstream>
#include <string>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "scene/run_scene.h"

using namespace incise;

namespace {

// The last frame's displacement of a scene given as text.
Eigen::VectorXd run_text(const std::string& text) {
  const Scene s = parse_scene(text, "scene.json");
  Eigen::VectorXd last;
  SceneRunOptions ro;
  ro.on_frame = [&](int, const Eigen::VectorXd& u, const FrameStats&) { last = u; };
  run_scene(s, ro);
  return last;
}

std::string error_of(const std::string& text) {
  try {
    run_text(text);
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no error)";
}

// Lame: radial displacement of a thick-walled cylinder (radii a < b) under internal pressure p,
// plane strain.
double lame_ur(double r, double a, double b, double p, double e, double nu) {
  return (1 + nu) * p * a * a / (e * (b * b - a * a)) * ((1 - 2 * nu) * r + b * b / r);
}

}  // namespace

TEST_CASE("rollers on three symmetry planes and a pulling pressure give exact uniaxial stress", "[scene][rollers]") {
  // Box [0,2]x[0,1]x[0,1]; x = 0 held in x, y = 0 in y, z = 0 in z; a pressure of -p on x = 2
  // pulls with traction p. Exact: u = (p x, -nu p y, -nu p z) / E, which linear tets reproduce.
  const double e = 2e3, nu = 0.3, p = 5;
  for (const char* model : {"fem-linear", "fem-corotational"}) {
    const std::string text = std::string(R"({
      "mesh": {"generate": "box", "size": [2, 1, 1], "cells": [4, 2, 3]},
      "model": ")") + model + R"(",
      "materials": {"*": {"young": 2e3, "poisson": 0.3}},
      "fixed": [{"box": [0, 0, 0, 0, 1, 1], "components": "x"}, {"box": [0, 0, 0, 2, 0, 1], "components": "y"},
                {"box": [0, 0, 0, 2, 1, 0], "components": "z"}],
      "loads": [{"type": "pressure", "box": [2, 0, 0, 2, 1, 1], "value": -5}],
      "solver": {"method": "direct", "nonlinear_iterations": 4},
      "time": {"frames": 1}
    })";
    const Eigen::VectorXd u = run_text(text);
    const TetMesh mesh = make_box(Vec3(2, 1, 1), {4, 2, 3});
    double worst = 0;
    for (VertexId v : mesh.vertices()) {
      const Vec3 x = mesh.rest(v);
      const Vec3 exact = Vec3(x.x(), -nu * x.y(), -nu * x.z()) * p / e;
      worst = std::max(worst, (u.segment<3>(3 * v.idx()) - exact).norm());
    }
    INFO(model);
    // Corotational: the rotations of a stretched box are the identity up to rounding.
    CHECK(worst < 1e-9 * p * 2 / e * 1e3);
  }
}

TEST_CASE("rollers that leave a rigid motion free are refused before solving", "[scene][rollers][errors]") {
  // Only the x = 0 face held in x: the body can still slide in y and z and turn about x.
  const std::string text = R"({
    "mesh": {"generate": "box", "size": [2, 1, 1], "cells": [2, 1, 1]},
    "fixed": [{"box": [0, 0, 0, 0, 1, 1], "components": "x"}],
    "loads": [{"type": "pressure", "box": [2, 0, 0, 2, 1, 1], "value": -5}],
    "time": {"frames": 1}
  })";
  const std::string err = error_of(text);
  CHECK_THAT(err, Catch::Contains("scene.json: fixed: static solve is under-constrained"));
  CHECK_THAT(err, Catch::Contains("whose held components leave a rigid motion free"));
  // The same face held in all three components blocks every rigid motion.
  std::string ok = text;
  ok.replace(ok.find("\"components\": \"x\""), 17, "\"components\": \"xyz\"");
  CHECK(error_of(ok) == "(no error)");
}

TEST_CASE("scene keys for rollers, pressure and formulation are checked", "[scene][errors]") {
  const std::string head = R"({"mesh": {"generate": "box"}, )";
  auto err = [&](const std::string& body) {
    try {
      parse_scene(head + body + "}", "s.json");
    } catch (const IoError& e) {
      return std::string(e.what());
    }
    return std::string("(no error)");
  };
  CHECK(err(R"("fixed": [{"box": [0,0,0,0,1,1], "components": "xq"}])") ==
        "s.json: fixed[0].components: expected the held components as letters, e.g. \"xyz\" or \"z\", got \"xq\"");
  CHECK_THAT(err(R"("fixed": [{"box": [0,0,0,0,1,1], "components": "xx"}])"), Catch::Contains("got \"xx\""));
  CHECK_THAT(err(R"("fixed": [{"box": [0,0,0,0,1,1], "components": ""}])"), Catch::Contains("fixed[0].components"));
  CHECK(err(R"("loads": [{"type": "pressure", "value": 1}])") ==
        "s.json: loads[0]: expected exactly one of \"tag\" and \"box\" to select the faces");
  CHECK(err(R"("loads": [{"type": "pressure", "value": 1, "tag": 1, "box": [0,0,0,1,1,1]}])") ==
        "s.json: loads[0]: expected exactly one of \"tag\" and \"box\" to select the faces");
  CHECK(err(R"("loads": [{"type": "pressure", "tag": 1}])") == "s.json: loads[0].value: missing");
  CHECK(err(R"("formulation": "locking-free")") ==
        "s.json: formulation: expected \"standard\", \"nodal-averaged\", \"edge-smoothed\", \"mixed\", "
        "\"mixed-edge-smoothed\", \"quadratic\" or \"mixed-quadratic\", got \"locking-free\"");
  CHECK_THAT(err(R"("model": "springs", "formulation": "mixed")"), Catch::Contains("formulation: is for FEM models"));
  CHECK_THAT(err(R"("model": "springs", "fixed": [{"box": [0,0,0,0,1,1], "components": "x"}])"),
             Catch::Contains("fixed[0].components: rollers are for FEM models"));
  CHECK_THAT(err(R"("materials": {"*": {"poisson": 0.5}})"),
             Catch::Contains("materials.*.poisson: Poisson's ratio 0.5 needs \"formulation\": \"mixed\""));
  CHECK_THAT(err(R"("materials": {"3": {"poisson": 0.5}}, "formulation": "nodal-averaged")"),
             Catch::Contains("materials.3.poisson: Poisson's ratio 0.5 needs"));
  CHECK_THAT(err(R"("materials": {"*": {"poisson": 0.51}})"), Catch::Contains("expected a Poisson's ratio in [0, 0.5]"));
  CHECK(err(R"("formulation": "nodal-averaged")") == "(no error)");
  CHECK(err(R"("mesh": {"generate": "tube", "radii": [2, 1]})").find("mesh.radii: expected inner < outer") != std::string::npos);
  // A pressure whose tag no face has, or whose box holds no face, is named at load time.
  CHECK_THAT(error_of(R"({"mesh": {"generate": "box"}, "fixed": [{"box": [0,0,0,0,1,1]}],
                          "loads": [{"type": "pressure", "tag": 40, "value": 1}], "time": {"frames": 1}})"),
             Catch::Contains("loads[0].tag: no boundary face has tag 40"));
  CHECK_THAT(error_of(R"({"mesh": {"generate": "box"}, "fixed": [{"box": [0,0,0,0,1,1]}],
                          "loads": [{"type": "pressure", "box": [0.2,0.2,0.2,0.8,0.8,0.8], "value": 1}], "time": {"frames": 1}})"),
             Catch::Contains("loads[0].box: selects no boundary face"));
}

TEST_CASE("make_tube tags its walls and approximates the sector's volume", "[mesh][generate]") {
  const double a = 1, b = 2, h = 0.5;
  const TetMesh m = make_tube(a, b, h, 90, {4, 24, 2});
  CHECK_NOTHROW(m.validate());
  double inner = 0, outer = 0, vol = 0;
  for (TetId t : m.tets()) {
    const auto v = m.tet_vertices(t);
    vol += (m.rest(v[1]) - m.rest(v[0])).cross(m.rest(v[2]) - m.rest(v[0])).dot(m.rest(v[3]) - m.rest(v[0])) / 6;
  }
  for (const BoundaryFace& f : m.boundary_faces()) {
    const double area = 0.5 * (m.rest(f.vertices[1]) - m.rest(f.vertices[0])).cross(m.rest(f.vertices[2]) - m.rest(f.vertices[0])).norm();
    if (f.tag == kTagTubeInner) inner += area;
    if (f.tag == kTagTubeOuter) outer += area;
  }
  // Chords of 24 segments over a quarter: within 0.2% of the curved values, and below them.
  const double exact_inner = M_PI / 2 * a * h, exact_outer = M_PI / 2 * b * h, exact_vol = M_PI / 4 * (b * b - a * a) * h;
  CHECK(inner < exact_inner);
  CHECK(inner > 0.998 * exact_inner);
  CHECK(outer > 0.998 * exact_outer);
  CHECK(vol > 0.998 * exact_vol);
  CHECK(vol < exact_vol);
  CHECK_THROWS_AS(make_tube(2, 1, h, 90, {1, 1, 1}), InvalidArgument);
  CHECK_THROWS_AS(make_tube(1, 2, h, 360, {1, 1, 1}), InvalidArgument);
  CHECK_THROWS_AS(make_tube(1, 2, h, 90, {1, 0, 1}), InvalidArgument);
}

TEST_CASE("Lame cylinder: internal pressure on a quarter tube on rollers matches the plane-strain solution",
          "[scene][rollers][verification]") {
  // a = 1, b = 2, p = 1, E = 1000, nu = 0.3; the standard formulation does not lock at this nu.
  const double a = 1, b = 2, p = 1, e = 1000, nu = 0.3;
  const std::string text = R"({
    "mesh": {"generate": "tube", "radii": [1, 2], "height": 0.25, "angle": 90, "cells": [8, 24, 1]},
    "materials": {"*": {"young": 1000, "poisson": 0.3}},
    "fixed": [{"box": [-1, 0, -1, 3, 0, 1], "components": "y"}, {"box": [0, -1, -1, 0, 3, 1], "components": "x"},
              {"box": [-1, -1, 0, 3, 3, 0], "components": "z"}, {"box": [-1, -1, 0.25, 3, 3, 0.25], "components": "z"}],
    "loads": [{"type": "pressure", "tag": 16, "value": 1}],
    "solver": {"method": "direct"},
    "time": {"frames": 1}
  })";
  const Eigen::VectorXd u = run_text(text);
  const TetMesh m = make_tube(1, 2, 0.25, 90, {8, 24, 1});
  double worst_inner = 0, worst_any = 0;
  for (VertexId v : m.vertices()) {
    const Vec3 x = m.rest(v);
    const double r = x.head<2>().norm();
    const double ur = u.segment<3>(3 * v.idx()).head<2>().dot(x.head<2>() / r);
    const double rel = std::abs(ur - lame_ur(r, a, b, p, e, nu)) / lame_ur(a, a, b, p, e, nu);
    worst_any = std::max(worst_any, rel);
    if (std::abs(r - a) < 1e-9) worst_inner = std::max(worst_inner, rel);
    CHECK(std::abs(u[3 * v.idx() + 2]) < 1e-12);  // plane strain: the end rollers hold z
  }
  INFO("worst relative error of u_r: inner wall " << worst_inner << ", anywhere " << worst_any);
  CHECK(worst_inner < 0.03);
  CHECK(worst_any < 0.03);
}

TEST_CASE("Lame cylinder per formulation: nodal-averaged, edge-smoothed and mixed do not lock, mixed holds at nu = 0.5",
          "[scene][rollers][verification][formulation][scale]") {
  // The same quarter tube and load as above at nu from 0.3 to 0.5: the inner wall's radial
  // displacement against the closed form. Standard tets lock as nu -> 0.5; the other two stay
  // within 3% and improve under refinement.
  const double a = 1, b = 2, p = 1, e = 1000;
  auto inner_error = [&](const char* formulation, double nu, int cells) {
    const std::string text = std::string(R"({"mesh": {"generate": "tube", "radii": [1, 2], "height": 0.25, "angle": 90,
      "cells": [)") + std::to_string(cells) + ", " + std::to_string(3 * cells) + R"(, 1]},
      "formulation": ")" + formulation + R"(", "materials": {"*": {"young": 1000, "poisson": )" + std::to_string(nu) + R"(}},
      "fixed": [{"box": [-1, 0, -1, 3, 0, 1], "components": "y"}, {"box": [0, -1, -1, 0, 3, 1], "components": "x"},
                {"box": [-1, -1, 0, 3, 3, 0], "components": "z"}, {"box": [-1, -1, 0.25, 3, 3, 0.25], "components": "z"}],
      "loads": [{"type": "pressure", "tag": 16, "value": 1}],
      "solver": {"method": "direct"}, "time": {"frames": 1}})";
    const Eigen::VectorXd u = run_text(text);
    const TetMesh m = make_tube(1, 2, 0.25, 90, {cells, 3 * cells, 1});
    double worst = 0;
    for (VertexId v : m.vertices()) {
      const Vec3 x = m.rest(v);
      const double r = x.head<2>().norm();
      if (std::abs(r - a) > 1e-9) continue;
      const double ur = u.segment<3>(3 * v.idx()).head<2>().dot(x.head<2>() / r);
      worst = std::max(worst, std::abs(ur - lame_ur(a, a, b, p, e, nu)) / lame_ur(a, a, b, p, e, nu));
    }
    return worst;
  };
  std::ostringstream table;
  for (double nu : {0.3, 0.49, 0.4999}) {
    const double st = inner_error("standard", nu, 12), na = inner_error("nodal-averaged", nu, 12),
                 es = inner_error("edge-smoothed", nu, 12), mx = inner_error("mixed", nu, 12);
    table << "nu " << nu << ": standard " << st << ", nodal-averaged " << na << ", edge-smoothed " << es << ", mixed "
          << mx << "\n";
    CHECK(na < 0.03);
    CHECK(es < 0.03);
    CHECK(mx < 0.03);
    if (nu > 0.49) CHECK(st > 5 * na);  // locked
  }
  const double coarse = inner_error("mixed", 0.5, 6), fine = inner_error("mixed", 0.5, 12);
  table << "nu 0.5 mixed: 6x18x1 " << coarse << ", 12x36x1 " << fine << "\n";
  CHECK(fine < 0.03);
  CHECK(fine < coarse);
  const double na_coarse = inner_error("nodal-averaged", 0.4999, 6), na_fine = inner_error("nodal-averaged", 0.4999, 12);
  table << "nu 0.4999 nodal-averaged: 6x18x1 " << na_coarse << ", 12x36x1 " << na_fine << "\n";
  CHECK(na_fine < na_coarse);
  WARN(table.str());
}
