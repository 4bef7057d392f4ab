// PETSc over MPI against incise's own solver: milliseconds of one static solve to a relative
// residual of 1e-8 from a cold start (assembly and preconditioner set-up included), iterations,
// peak memory per rank and per tet. docs/solver.md#petsc-more-than-one-machine has the figures.
//   bench_petsc --mesh cantilever [--cells 120,36,36] | --mesh FILE   --solver petsc | incise
//   mpirun -np 2 bench_petsc ... --solver petsc       (PETSC_OPTIONS=-log_view: PETSc's breakdown)
// incise: CG with its aggregation multigrid (--preconditioner to change it), one process.
// The load: linear standard tets, gravity; the cantilever clamped at x = 0, a mesh from a file
// (an organ) held on its lowest 15% (z). One CSV line on stdout (rank 0), then PETSc's log.
#include <cstdio>
#include <memory>
#include <string>

#include "bench/bench_common.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "mesh/rest_bounds.h"
#include "sim/fem/fem_simulation.h"
#include "sim/petsc/petsc_session.h"
#include "sim/linalg/preconditioner.h"

using namespace incise;
using namespace incise::bench;

int main(int argc, char** argv) {
  if (petsc_start_distributed() != 0) return petsc_serve();
  const Args args(argc, argv);
  const std::string mesh_arg = args.get("--mesh", "cantilever"), solver = args.get("--solver", "petsc");
  TetMesh m;
  if (mesh_arg == "cantilever") {
    const std::vector<double> c = args.list("--cells", "120,36,36");
    m = make_box(Vec3(c[0] / c[1], 1, c[2] / c[1]), {int(c[0]), int(c[1]), int(c[2])});
  } else {
    m = read_tet_mesh(mesh_arg);
  }
  m.discard_change();
  FemSimulationOptions o;
  o.cg.tolerance = std::stod(args.get("--tolerance", "1e-8"));
  o.cg.max_iterations = 20000;
  o.gravity = Vec3(0, 0, -9.81);
  o.warm_start = false;
  if (solver == "petsc") o.backend = StiffnessBackend::Petsc;
  else o.cg.preconditioner = parse_preconditioner(args.get("--preconditioner", "amg"));
  const double t0 = now_ms();
  // The simulation (and its PETSc solver) goes before petsc_finish(): freeing PETSc objects is
  // collective, every rank must have done it when PETSc finalizes.
  auto sim_ptr = std::make_unique<FemSimulation>(m, MaterialTable(Material{1e5, 0.3, 1000}), o);
  FemSimulation& sim = *sim_ptr;
  const RestBounds box = rest_bounds(m);
  const Vec3 lo = box.lo, hi = box.hi;
  for (VertexId v : m.vertices()) {
    const Vec3 p = m.rest(v);
    if (mesh_arg == "cantilever" ? p.x() < lo.x() + 1e-9 : p.z() < lo.z() + 0.15 * (hi.z() - lo.z())) sim.fix(v);
  }
  const FrameStats st = sim.step();
  const double total = now_ms() - t0;
  sim_ptr.reset();
  const std::vector<double> mem = rank_peak_memory_mb();
  double mem_sum = 0;
  std::string mem_list;
  for (double x : mem) {
    mem_sum += x;
    mem_list += (mem_list.empty() ? "" : "/") + std::to_string(int(x + 0.5));
  }
  const int ranks = std::max<int>(1, int(mem.size()));
  std::printf("mesh,tets,solver,ranks,iterations,relative_residual,setup_ms,solve_ms,total_ms,peak_mb_per_rank,bytes_per_tet\n");
  std::printf("%s,%zu,%s,%d,%d,%.2e,%.0f,%.0f,%.0f,%s,%.0f\n", mesh_arg.c_str(), m.num_tets(),
              solver == "petsc" ? "petsc-gamg" : ("incise-cg-" + args.get("--preconditioner", "amg")).c_str(), ranks,
              st.iterations, st.relative_residual, st.preconditioner_setup_ms, st.solve_ms - st.preconditioner_setup_ms,
              total, mem_list.c_str(), mem_sum * 1048576.0 / double(m.num_tets()));
  if (st.info != SolveInfo::Success) std::fprintf(stderr, "bench_petsc: not converged: %s\n", st.message.c_str());
  std::fflush(stdout);
  petsc_finish(0);
  return st.info == SolveInfo::Success ? 0 : 1;
}
