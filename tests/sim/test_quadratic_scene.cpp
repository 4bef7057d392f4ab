// Quadratic tets end to end through a scene: "formulation": "quadratic" runs, its frames are
// VTK quadratic tets that meshio reads as tetra10, and options they cannot honour are refused.
#include <catch2/catch.hpp>

#include <cstdlib>
#include <fstream>

#include "mesh/errors.h"
#include "mesh/io/tet_io.h"
#include "scene/run_scene.h"
#include "scene/scene.h"
#include "scene/scene_runner.h"
#include "sim/fem/quadratic_solver.h"
#include "tests/io/io_test_util.h"

using namespace incise;
using incise::testing::ScratchDir;

namespace {

// The sample beam (12 x 3 x 3 cm) clamped at x = 0 under gravity and a tip traction.
std::string beam_scene(const std::string& formulation, const std::string& model, const std::string& extra = "") {
  return R"({"units": "m", "mesh": ")" + std::string(INCISE_SOURCE_DIR) + R"(/samples/scenes/beam.vtu",
    "model": ")" + model + R"(", "formulation": ")" + formulation + R"(",
    "materials": {"*": {"young": 1e5, "poisson": 0.45, "density": 1000}},
    "fixed": [{"box": [-0.001, -0.001, -0.001, 0.0001, 0.031, 0.031]}],
    "loads": [{"type": "gravity", "g": [0, 0, -9.81]},
              {"type": "traction", "box": [0.1199, -0.001, -0.001, 0.121, 0.031, 0.031], "value": [0, 0, -200]}],
    "solver": {"method": "direct"}, "time": {"frames": 1})" + extra + "}";
}

}  // namespace

TEST_CASE("a quadratic scene runs and writes quadratic tets that meshio reads as tetra10", "[quadratic][meshio]") {
  ScratchDir dir("quadratic_scene");
  const std::string path = dir / "beam.json";
  std::ofstream(path) << beam_scene("quadratic", "fem-linear");
  const Scene scene = load_scene(path);
  SceneRunOptions ro;
  ro.out_dir = dir / "run";
  const SceneRunSummary sum = run_scene(scene, ro);
  CHECK(sum.frames == 1);
  CHECK(sum.frames_not_converged == 0);
  // incise reads the frame back as its corners.
  const TetMesh linear = load_scene_mesh(scene);
  ReadReport rep;
  const TetMesh back = read_tet_mesh(dir / "run/frame_0000.vtu", &rep);
  CHECK(back.num_tets() == linear.num_tets());
  // The same scene on linear tets sags less: P2 has no shear locking in bending.
  std::ofstream(dir / "linear.json") << beam_scene("standard", "fem-linear");
  SceneRunner lin(load_scene(dir / "linear.json"));
  const SceneFrame lf = lin.step();
  SceneRunner quad(scene);
  const SceneFrame qf = quad.step();
  CHECK(qf.max_displacement > lf.max_displacement);
  CHECK(qf.max_displacement < 1.5 * lf.max_displacement);
  if (!incise::testing::have_meshio()) {
    WARN("/usr/bin/python3 has no meshio; skipping the meshio check");
    return;
  }
  const std::size_t edges = quad.fem()->quadratic()->p2().edges.size();
  const std::string cmd = "/usr/bin/python3 -c \"import meshio, sys; m = meshio.read(sys.argv[1]); "
                          "c = [b for b in m.cells if b.type == 'tetra10']; "
                          "assert len(c) == 1 and len(c[0].data) == int(sys.argv[2]), [b.type for b in m.cells]; "
                          "assert len(m.points) == int(sys.argv[3]), len(m.points); "
                          "assert m.point_data['displacement'].shape == (len(m.points), 3)\" '" +
                          dir / "run/frame_0000.vtu" + "' " + std::to_string(linear.num_tets()) + " " +
                          std::to_string(linear.num_vertices() + edges);
  CHECK(std::system(cmd.c_str()) == 0);
}

TEST_CASE("quadratic scenes refuse what they cannot honour, naming the file and key", "[quadratic]") {
  const auto refused = [](const std::string& text, const std::string& what) {
    try {
      (void)parse_scene(text, "q.json");
      FAIL("accepted: " << what);
    } catch (const IoError& e) {
      CHECK_THAT(e.what(), Catch::Contains("q.json") && Catch::Contains(what));
    }
  };
  refused(beam_scene("quadratic", "fem-linear", R"(, "cuts": [{"blade": [[0.06, -0.01, 0.04], [0.06, 0.04, 0.04]], "sweep": [0, 0, -0.02], "from_frame": 0, "to_frame": 0}])"),
          "cuts: quadratic tets");
  std::string budget = beam_scene("quadratic", "fem-linear");
  budget.replace(budget.find(R"("method": "direct")"), 18, R"("method": "cg", "budget_ms": 10)");
  refused(budget, "solver.budget_ms");
  std::string amg = beam_scene("mixed-quadratic", "fem-linear");
  amg.replace(amg.find(R"("method": "direct")"), 18, R"("method": "cg", "preconditioner": "amg")");
  refused(amg, "solver.preconditioner");
  // Poisson's ratio 0.5: Taylor-Hood takes it, P2 alone does not.
  std::string half = beam_scene("quadratic", "fem-linear");
  half.replace(half.find("0.45"), 4, "0.5");
  refused(half, "poisson");
  std::string th = beam_scene("mixed-quadratic", "fem-corotational");
  th.replace(th.find("0.45"), 4, "0.5");
  CHECK_NOTHROW(parse_scene(th, "q.json"));
}
