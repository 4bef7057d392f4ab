// Local update vs full rebuild after k edited tets in an N-tet mesh. Local: FemModel::apply on
// the batch's TopologyChange (per-tet data of the added tets, diagonal/mass/incidence slots of
// the touched vertices). Rebuild baselines: a new FemModel (all per-tet data + Jacobi
// diagonal), and reassembling the sparse matrix (AssembledStiffness::rebuild: reassembly +
// preconditioner diagonal).
//   bench_fem_local_update [--sizes 10000,100000,1000000] [--edits 1,10,100,1000] [--out DIR]
#include <cmath>
#include <random>

#include "bench/bench_common.h"
#include "mesh/generate.h"
#include "sim/fem/assembled_stiffness.h"
#include "sim/fem/fem_model.h"
#include "testing/mesh_edits.h"

using namespace incise;
using incise::testing::random_tet;
using namespace incise::bench;

namespace {

// Splits until `k` tets have been replaced (the change's removed tets), like a cut would.
void edit(TetMesh& m, std::mt19937& rng, int k) {
  std::uniform_real_distribution<double> u(0.3, 0.7);
  std::uniform_int_distribution<int> op(0, 2), loc(0, 3);
  int done = 0;
  while (done < k) {
    const TetId t = random_tet(m, rng);
    const auto v = m.tet_vertices(t);
    switch (op(rng)) {
      case 0: {
        const auto n = m.edge_star(v[0], v[1]).tets.size();
        m.split_edge(v[0], v[1], u(rng));
        done += int(n);
        break;
      }
      case 1: {
        m.split_face(t, loc(rng));
        done += m.neighbor(t, 0).is_valid() ? 2 : 1;
        break;
      }
      default:
        m.split_tet(t);
        done += 1;
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  Args args(argc, argv);
  const auto sizes = args.list("--sizes", "10000,100000,1000000");
  const auto edits = args.list("--edits", "1,10,100,1000");
  Csv csv(args.get("--out", "."), "fem_local_update.csv",
          "tets,edited_tets,local_ms,tets_recomputed,vertices_updated,rebuild_model_ms,reassemble_ms,"
          "speedup_vs_model,speedup_vs_reassembly");
  std::printf("local update vs full rebuild (median of 5 batches each)\n");
  std::printf("%9s %7s %10s %8s %8s %12s %12s %10s %10s\n", "tets", "edited", "local ms", "tets", "verts", "rebuild ms",
              "reassem. ms", "x model", "x reassem.");
  for (double target : sizes) {
    const int n = std::max(1, int(std::lround(std::cbrt(target / 6))));
    TetMesh m = make_box(Vec3(1, 1, 1), {n, n, n});
    m.discard_change();
    const MaterialTable mats{Material{}};
    FemModel model(m, mats);
    AssembledStiffness as(model);
    std::mt19937 rng(7);
    const double rebuild = time_ms(3, [&] { FemModel fresh(m, mats); });
    const double reassemble = time_ms(3, [&] { as.rebuild(); });
    for (double kd : edits) {
      const int k = int(kd);
      std::vector<double> times;
      std::uint64_t tets = 0, verts = 0;
      for (int rep = 0; rep < 5; ++rep) {
        edit(m, rng, k);
        const TopologyChange ch = m.take_change();
        model.reset_work();
        const double t0 = now_ms();
        model.apply(ch);
        times.push_back(now_ms() - t0);
        tets += model.work().tets_recomputed;
        verts += model.work().vertices_updated;
      }
      std::sort(times.begin(), times.end());
      const double local = times[2];
      csv.row(m.num_tets(), k, local, tets / 5.0, verts / 5.0, rebuild, reassemble, rebuild / local, reassemble / local);
      std::printf("%9zu %7d %10.4f %8.0f %8.0f %12.2f %12.2f %10.0f %10.0f\n", m.num_tets(), k, local, tets / 5.0,
                  verts / 5.0, rebuild, reassemble, rebuild / local, reassemble / local);
    }
  }
  std::printf("x model / x reassem.: how many times faster the local update is than each rebuild.\n");
  return 0;
}
