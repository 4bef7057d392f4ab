// libFuzzer harness for the TopologyChange checks (mesh/change_follower.h): the FEM and the
// springs follow a mesh that is edited (edge and tet splits, flips) and are handed its changes
// -- or forged ones: another mesh's, repeats, skips, stale ones, hand-made ones whose ids are
// taken from the input. A change must be refused with incise::Error or applied; after an
// applied one both backends step to finite positions (when the input asks, and at the end). Anything else (a crash, a sanitizer
// report, a NaN) is a bug.
//
// Byte 0: seed of the forgery choices. Then 3 bytes per action (32 at most): the action, and two
// operands (ids modulo the mesh's capacities, a split parameter).
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "sim/fem/fem_simulation.h"
#include "sim/springs/spring_model.h"

namespace {

using namespace incise;

struct Backends {
  TetMesh& mesh;
  FemSimulation fem;
  SpringModel springs;
  explicit Backends(TetMesh& m)
      : mesh(m), fem(m, MaterialTable(Material{1e4, 0.3, 1000}), options()), springs(m, MaterialTable(Material{1e4, 0.3, 1000})) {
    for (VertexId v : m.vertices())
      if (m.rest(v).x() < 1e-9) {
        fem.fix(v);
        springs.set_fixed(v, true);
      }
    fem.set_gravity(Vec3(0, 0, -9.81));
    springs.set_gravity(Vec3(0, 0, -9.81));
  }
  static FemSimulationOptions options() {
    FemSimulationOptions o;
    o.cg.max_iterations = 50;
    o.cg.budget_ms = 0;
    return o;
  }
  // Hands `c` to both; a refusal must come before either touched its data, so the two agree.
  void offer(const TopologyChange& c) {
    bool fem_ok = true, springs_ok = true;
    try {
      fem.apply(c);
    } catch (const Error&) {
      fem_ok = false;
    }
    try {
      springs.apply(mesh, c);
    } catch (const Error&) {
      springs_ok = false;
    }
    if (fem_ok != springs_ok) std::abort();
  }
  void step() {
    try {
      fem.step();
      springs.step(1e-4, Integrator::SymplecticEuler);
    } catch (const Error&) {
      return;  // a refused solve is a report, not a crash
    }
    for (VertexId v : mesh.vertices())
      if (!springs.positions()[v.idx()].allFinite()) std::abort();
    const Eigen::VectorXd& u = fem.displacement();
    for (Eigen::Index i = 0; i < u.size(); ++i)
      if (!std::isfinite(u[i])) std::abort();
  }
};

VertexId nth_vertex(const TetMesh& m, std::uint8_t k) {
  const auto vs = m.vertices();
  return vs[k % vs.size()];
}
TetId nth_tet(const TetMesh& m, std::uint8_t k) {
  const auto ts = m.tets();
  return ts[k % ts.size()];
}

// A change forged from `real` (taken from the mesh just now) by the rule `how`.
TopologyChange forge(const TopologyChange& real, const TetMesh& m, std::uint8_t how, std::uint8_t a, std::uint8_t b) {
  TopologyChange c = real;
  switch (how % 8) {
    case 0: break;                                  // the real one
    case 1: c.mesh ^= 1; break;                     // another mesh's
    case 2: c.serial += 1 + a % 3; break;           // a skip
    case 3: c.serial = 0; break;                    // made by hand, as recorded
    case 4:                                         // by hand, naming an id past the mesh
      c.serial = 0;
      c.added_tets.push_back(TetId(std::uint32_t(m.tet_capacity() + a)));
      break;
    case 5:                                         // by hand, a live tet as removed
      c.serial = 0;
      c.removed_tets.push_back(nth_tet(m, a));
      break;
    case 6:                                         // by hand, a vertex with parents past the mesh
      c.serial = 0;
      c.added_vertices.push_back(VertexOrigin{nth_vertex(m, a), {VertexId(std::uint32_t(m.vertex_capacity() + b)),
                                                                 VertexId(), VertexId(), VertexId()},
                                              {1, 0, 0, 0}});
      break;
    case 7:                                         // by hand, a touched vertex that is dead or past the mesh
      c.serial = 0;
      c.touched_vertices.push_back(VertexId(std::uint32_t(m.vertex_capacity() + a)));
      break;
  }
  return c;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static const TetMesh base = [] {
    TetMesh m = make_box(Vec3(1, 0.5, 0.5), {2, 1, 1});
    m.discard_change();
    return m;
  }();
  TetMesh mesh = base;
  TetMesh other = base;  // a second mesh: its changes are foreign to the backends
  Backends b(mesh);
  std::uint8_t seed = data[0];
  std::vector<TopologyChange> history;
  const std::size_t actions = std::min<std::size_t>((size - 1) / 3, 32);
  for (std::size_t k = 0; k < actions; ++k) {
    const std::uint8_t op = data[1 + 3 * k], x = data[2 + 3 * k], y = data[3 + 3 * k];
    seed = std::uint8_t(seed * 33 + op);
    try {
      switch (op % 6) {
        case 0: {  // split an edge of a tet
          const TetId t = nth_tet(mesh, x);
          const auto tv = mesh.tet_vertices(t);
          const int i = y % 4, j = (i + 1 + (y / 4) % 3) % 4;  // two different corners
          mesh.split_edge(tv[i], tv[j], 0.1 + 0.8 * (y / 255.0));
          break;
        }
        case 1:
          mesh.split_tet(nth_tet(mesh, x));
          break;
        case 2: {  // a 2-3 flip where it is allowed
          const TetId t = nth_tet(mesh, x);
          if (mesh.is_flip23_ok(t, y % 4)) mesh.flip23(t, y % 4);
          break;
        }
        case 3:  // an edit of the other mesh, whose change is offered here
          other.split_tet(nth_tet(other, x));
          b.offer(other.take_change());
          continue;
        case 4:  // an old change again (a repeat, or stale)
          if (!history.empty()) b.offer(history[x % history.size()]);
          continue;
        case 5:
          b.step();
          continue;
      }
    } catch (const Error&) {
      continue;  // an edit the mesh refused changes nothing
    }
    const TopologyChange real = mesh.take_change();
    if (real.empty()) continue;
    const TopologyChange forged = forge(real, mesh, seed, x, y);
    b.offer(forged);
    if (seed % 8 != 0) b.offer(real);  // the real one after a forgery: applied unless the forgery was
    history.push_back(real);
  }
  b.step();
  return 0;
}
