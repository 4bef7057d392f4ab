// Files written by the real programs: gmsh (msh 1, 2.2, 4.1) and tetgen (-pq, -pqA).
#include <map>

#include "io_test_util.h"
#include "mesh/errors.h"

using namespace incise;
using namespace incise::testing;

namespace {
bool have_program(const char* name) {
  return std::system((std::string("command -v ") + name + " >/dev/null 2>&1").c_str()) == 0;
}
}  // namespace

TEST_CASE("gmsh output in every .msh version", "[io][gmsh]") {
  if (!have_program("gmsh")) {
    WARN("gmsh not installed; skipping");
    return;
  }
  ScratchDir dir("gmsh");
  const std::string geo = std::string(INCISE_SOURCE_DIR) + "/tests/io/data/two_boxes.geo";
  double volume = -1;
  std::size_t tets = 0;
  for (std::string fmt : {"msh1", "msh22", "msh41"}) {
    INFO(fmt);
    const std::string out = dir / ("two_" + fmt + ".msh");
    std::string cmd = "gmsh -3 " + geo + " -o " + out + " -format " + fmt + " -v 0 > /dev/null 2>&1";
    REQUIRE(std::system(cmd.c_str()) == 0);
    ReadReport r;
    TetMesh m = read_tet_mesh(out, &r);
    m.validate(TetMesh::ValidateOptions{true, true});
    CHECK(r.format.rfind("gmsh", 0) == 0);
    CHECK(r.reoriented_tets == 0);
    CHECK(m.total_volume() == Approx(2.0).epsilon(1e-12));
    // The same mesh whatever the version.
    if (volume < 0) {
      volume = m.total_volume();
      tets = m.num_tets();
    }
    CHECK(m.num_tets() == tets);
    // Two physical volumes, each of volume 1.
    std::map<int, double> by_label;
    for (TetId t : m.tets()) by_label[m.label(t)] += m.volume(t);
    REQUIRE(by_label.size() == 2);
    CHECK(by_label[7] == Approx(1.0));
    CHECK(by_label[9] == Approx(1.0));
    // Physical surface 21 (x = 0) tags its boundary faces; the rest keep kTagSurface.
    double tagged_area = 0;
    for (const auto& f : m.boundary_faces()) {
      const Vec3 &a = m.rest(f.vertices[0]), &b = m.rest(f.vertices[1]), &c = m.rest(f.vertices[2]);
      if (f.tag == 21) {
        tagged_area += 0.5 * (b - a).cross(c - a).norm();
        CHECK(std::abs(a.x()) + std::abs(b.x()) + std::abs(c.x()) == 0.0);
      } else {
        CHECK(f.tag == kTagSurface);
      }
    }
    CHECK(tagged_area == Approx(1.0));
    // And back out through incise's writer, into gmsh again.
    const std::string back = dir / ("back_" + fmt + ".msh");
    write_tet_mesh(m, back);
    const std::string again = dir / ("again_" + fmt + ".msh");
    cmd = "gmsh " + back + " -0 -o " + again + " -format msh22 -v 0 > /dev/null 2>&1";
    REQUIRE(std::system(cmd.c_str()) == 0);
    TetMesh g = read_tet_mesh(again);
    CHECK(g.num_tets() == m.num_tets());
    CHECK(g.total_volume() == Approx(2.0));
  }
}

TEST_CASE("tetgen output, with and without region attributes", "[io][tetgen]") {
  if (!have_program("tetgen")) {
    WARN("tetgen not installed; skipping");
    return;
  }
  ScratchDir dir("tetgen");
  // A unit cube as an OFF surface.
  write_text(dir / "cube.off",
             "OFF\n8 12 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
             "3 0 2 1\n3 0 3 2\n3 4 5 6\n3 4 6 7\n3 0 1 5\n3 0 5 4\n3 1 2 6\n3 1 6 5\n3 2 3 7\n3 2 7 6\n3 3 0 4\n3 3 4 7\n");
  REQUIRE(std::system(("cd " + dir.path.string() + " && tetgen -pqQ cube.off > /dev/null 2>&1").c_str()) == 0);
  for (std::string name : {"cube.1.node", "cube.1.ele"}) {
    ReadReport r;
    TetMesh m = read_tet_mesh(dir / name, &r);
    m.validate(TetMesh::ValidateOptions{true, true});
    CHECK(r.format == "tetgen");
    CHECK(r.reoriented_tets == 0);
    CHECK(m.total_volume() == Approx(1.0).epsilon(1e-12));
    CHECK(m.num_tets() >= 5);
  }
  // Two regions: -A writes the region attribute, which becomes the label.
  const std::string poly = std::string(INCISE_SOURCE_DIR) + "/tests/io/data/two_regions.poly";
  std::filesystem::copy_file(poly, dir / "two.poly");
  REQUIRE(std::system(("cd " + dir.path.string() + " && tetgen -pqAQ two.poly > /dev/null 2>&1").c_str()) == 0);
  TetMesh m = read_tet_mesh(dir / "two.1.ele");
  m.validate(TetMesh::ValidateOptions{true, true});
  std::map<int, double> by_label;
  for (TetId t : m.tets()) by_label[m.label(t)] += m.volume(t);
  REQUIRE(by_label.size() == 2);
  CHECK(by_label[3] == Approx(1.0));
  CHECK(by_label[5] == Approx(1.0));
  // And incise's TetGen output goes back into tetgen (-r refines an existing mesh).
  write_tet_mesh(m, dir / "mine.node");
  REQUIRE(std::system(("cd " + dir.path.string() + " && tetgen -rqQ mine > /dev/null 2>&1").c_str()) == 0);
  TetMesh refined = read_tet_mesh(dir / "mine.1.node");
  CHECK(refined.total_volume() == Approx(2.0));
}
