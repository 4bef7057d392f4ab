// Quadratic tets against CalculiX's C3D10 (Debian's calculix-ccx): the same mesh, material,
// supports and loads written to an .inp file, solved by ccx, its displacements read back from
// the .dat file. Skipped (with a warning) when ccx is not on the PATH.
#include <catch2/catch.hpp>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "mesh/generate.h"
#include "sim/fem/fem_simulation.h"
#include "sim/fem/quadratic_solver.h"
#include "tests/io/io_test_util.h"
#include "testing/mesh_edits.h"

using namespace incise;
using incise::testing::ScratchDir;

namespace {

bool have_ccx() { return std::system("command -v ccx >/dev/null 2>&1") == 0; }

// The P2 mesh as C3D10 elements (node n is ccx node n + 1; VTK's order is C3D10's), the held
// nodes, nodal loads `f` (every node's, as *CLOAD) and gravity as *DLOAD GRAV.
void write_inp(const std::string& path, const TetMesh& m, const P2Mesh& p2, const Material& mat,
               const std::vector<std::size_t>& held, const Eigen::VectorXd& f, const Vec3& g) {
  std::ofstream o(path);
  o.precision(17);
  o << "*NODE, NSET=NALL\n";
  for (std::size_t n = 0; n < p2.num_nodes(); ++n) {
    if (n < p2.corner_slots && m.incident_tets(VertexId(std::uint32_t(n))).empty()) continue;
    const Vec3 x = p2.rest(m, n);
    o << n + 1 << ", " << x.x() << ", " << x.y() << ", " << x.z() << "\n";
  }
  o << "*ELEMENT, TYPE=C3D10, ELSET=EALL\n";
  std::size_t e = 0;
  for (TetId t : m.tets()) {
    o << ++e;
    for (std::uint32_t n : p2.tets[t.idx()]) o << ", " << n + 1;
    o << "\n";
  }
  o << "*MATERIAL, NAME=TISSUE\n*ELASTIC\n" << mat.young << ", " << mat.poisson << "\n*DENSITY\n" << mat.density << "\n";
  o << "*SOLID SECTION, ELSET=EALL, MATERIAL=TISSUE\n*BOUNDARY\n";
  for (std::size_t n : held) o << n + 1 << ", 1, 3, 0.0\n";
  o << "*STEP\n*STATIC\n*CLOAD\n";
  for (std::size_t n = 0; n < p2.num_nodes(); ++n)
    for (int k = 0; k < 3; ++k)
      if (f[3 * Eigen::Index(n) + k] != 0) o << n + 1 << ", " << k + 1 << ", " << f[3 * Eigen::Index(n) + k] << "\n";
  o << "*DLOAD\nEALL, GRAV, " << g.norm() << ", " << g.x() / g.norm() << ", " << g.y() / g.norm() << ", "
    << g.z() / g.norm() << "\n";
  o << "*NODE PRINT, NSET=NALL\nU\n*END STEP\n";
}

// The displacements ccx printed (node -> u), from the .dat file's block after "displacements".
std::vector<std::pair<std::size_t, Vec3>> read_dat(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::vector<std::pair<std::size_t, Vec3>> out;
  bool in_block = false;
  while (std::getline(in, line)) {
    if (line.find("displacements") != std::string::npos) {
      in_block = true;
      continue;
    }
    if (!in_block) continue;
    std::istringstream ls(line);
    std::size_t node;
    Vec3 u;
    if (ls >> node >> u.x() >> u.y() >> u.z()) out.emplace_back(node - 1, u);
  }
  return out;
}

}  // namespace

TEST_CASE("quadratic tets equal CalculiX C3D10 on a jittered cantilever", "[quadratic][calculix]") {
  if (!have_ccx()) {
    WARN("ccx (Debian calculix-ccx, scripts/install-deps.sh) is not on the PATH; skipping the CalculiX comparison");
    return;
  }
  TetMesh m = make_box(Vec3(4, 1, 1), {6, 2, 2});
  incise::testing::jitter(m, 0.3, 11);
  const Material mat{2e5, 0.35, 1000};
  const Vec3 g(0, 0, -9.81);
  QuadraticOptions o;
  QuadraticSolver qs(m, MixedMaterials(mat), FemKind::Linear, o);
  const P2Mesh& p2 = qs.p2();
  // Clamped at x = 0 (corner and mid-edge nodes), a shear traction on the tip face x = 4.
  std::vector<std::size_t> held;
  std::vector<std::uint8_t> free(qs.num_dofs(), 1);
  for (std::size_t n = 0; n < p2.num_nodes(); ++n)
    if (p2.rest(m, n).x() < 1e-9) {
      held.push_back(n);
      for (int k = 0; k < 3; ++k) free[3 * n + std::size_t(k)] = 0;
    }
  Eigen::VectorXd f = Eigen::VectorXd::Zero(Eigen::Index(qs.num_dofs()));
  for (const BoundaryFace& bf : m.boundary_faces()) {
    bool tip = true;
    for (VertexId v : bf.vertices) tip = tip && m.rest(v).x() > 4 - 1e-9;
    if (tip) qs.add_face_traction(bf.vertices[0], bf.vertices[1], bf.vertices[2], Vec3(0, 300, -2000), f);
  }
  Eigen::VectorXd u = Eigen::VectorXd::Zero(f.size());
  REQUIRE(qs.solve(0, 1, f + qs.body_force(g), free, u).converged);

  ScratchDir dir("calculix_c3d10");
  write_inp(dir / "beam.inp", m, p2, mat, held, f, g);
  const std::string cmd = "cd '" + dir.path.string() + "' && OMP_NUM_THREADS=1 ccx -i beam > ccx.log 2>&1";
  REQUIRE(std::system(cmd.c_str()) == 0);
  const auto ccx = read_dat(dir / "beam.dat");
  REQUIRE(ccx.size() == p2.num_nodes());
  double umax = 0, diff = 0;
  for (const auto& [n, uc] : ccx) {
    REQUIRE(n < p2.num_nodes());
    umax = std::max(umax, uc.norm());
    diff = std::max(diff, (u.segment<3>(3 * Eigen::Index(n)) - uc).norm());
  }
  INFO("max |u| " << umax << ", max |u - u_ccx| " << diff);
  CHECK(umax > 0);
  CHECK(diff <= 1e-6 * umax);
}
