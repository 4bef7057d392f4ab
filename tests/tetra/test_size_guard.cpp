// Issue 38 item 10: meshing requests whose size is far past what the input needs are refused
// before (or early in) the work, with one message naming the estimate: a flat surface, a
// feature edge size that asks for millions of protecting balls, a facet distance that keeps
// refining, a size needing more tets than the limit.
#include <catch2/catch.hpp>

#include <chrono>

#include "mesh/errors.h"
#include "mesh/tetrahedralize/pipeline.h"
#include "tests/tetra/shapes.h"

using namespace incise;
using namespace incise::testing;

namespace {

std::string refusal(const SurfaceMesh& s, const PipelineOptions& opt) {
  try {
    mesh_surface(s, opt);
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("size guard: a flat surface is refused, also with --repair", "[tetra][cgal][size]") {
  SurfaceMesh flat;
  flat.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)};
  flat.triangles = {{0, 1, 2}, {0, 2, 3}};
  for (bool repair : {false, true}) {
    PipelineOptions opt;
    opt.repair = repair;
    const auto t0 = std::chrono::steady_clock::now();
    const std::string why = refusal(flat, opt);
    INFO(why);
    CHECK(why.find("the surface is flat") != std::string::npos);
    CHECK(std::chrono::steady_clock::now() - t0 < std::chrono::seconds(10));  // not a hang: refused up front
  }
  // A thin box is not flat: it is meshed.
  PipelineOptions opt;
  opt.tetra.size = Length{0.1, false};
  CHECK(mesh_surface(box_surface(Vec3(1, 1, 0.1)), opt).num_tets() > 0);
}

TEST_CASE("size guard: feature protection and refinement are bounded", "[tetra][cgal][size]") {
  const SurfaceMesh box = box_surface(Vec3(1, 1, 1));
  SECTION("an edge size that would need millions of protecting balls") {
    PipelineOptions opt;
    opt.tetra.features_angle = 89;  // the box's edges are 90 degrees
    opt.tetra.edge_size = Length{1e-7, false};
    const std::string why = refusal(box, opt);
    INFO(why);
    CHECK(why.find("edge size 1e-07 would need about") != std::string::npos);
    CHECK(why.find("protecting balls along the features") != std::string::npos);
  }
  SECTION("a facet distance that keeps refining is stopped at the vertex limit") {
    PipelineOptions opt;
    opt.tetra.facet_distance = Length{1e-12, false};
    opt.tetra.max_tets = 40000;  // the limit: 10000 vertices (about 20k tets expected)
    const std::string why = refusal(sphere_surface(1, 3), opt);
    INFO(why);
    CHECK(why.find("refinement passed 10000 vertices") != std::string::npos);
    CHECK(why.find("facet distance 1e-12") != std::string::npos);
  }
  SECTION("a size needing more tets than the limit, named in the message") {
    PipelineOptions opt;
    opt.tetra.size = Length{1e-9, false};
    const std::string why = refusal(box, opt);
    INFO(why);
    CHECK(why.find("would need about 5.56e+27 tets") != std::string::npos);  // volume 1 / (0.18 size^3)
  }
}
