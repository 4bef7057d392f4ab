// K*x: matrix-free (slab-coloured packets, sim/fem/stiffness_kernel.h) vs the assembled sparse
// matrix (our TBB CSR product and Eigen's serial SpMV), linear and corotational, on box meshes
// from 10k to 1M tets, with 1 and 2 threads, next to a STREAM-triad bandwidth measurement in
// the same run: ratio and percent of the memory-bandwidth bound.
// Then the formulations: corotational K*x of standard, nodal-averaged and edge-smoothed tets,
// matrix-free against their assembled matrices (nodal-averaged's reaches the 2-ring), on a mesh
// file (--organ) or a box of about 27k tets.
//   bench_fem_kx [--sizes 10000,100000,1000000] [--reps 7] [--linear-only] [--organ MESH] [--out DIR]
#include <cmath>
#include <random>

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include "bench/bench_common.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "sim/fem/assembled_stiffness.h"
#include "sim/fem/fem_model.h"

using namespace incise;
using namespace incise::bench;

namespace {

// STREAM triad a = b + s c over 3 x 32M doubles (768 MB): GB/s counting 3 x 8 bytes per entry.
double stream_triad_gbs(int reps) {
  const std::size_t n = std::size_t(1) << 25;
  std::vector<double> a(n, 0.0), b(n, 1.0), c(n, 2.0);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n), [&](auto r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) a[i] = b[i] = c[i] = 1.0;
  });
  const double ms = time_ms(reps, [&] {
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1 << 16), [&](auto r) {
      for (std::size_t i = r.begin(); i != r.end(); ++i) a[i] = b[i] + 3.0 * c[i];
    });
  });
  return 3.0 * 8.0 * double(n) / (ms * 1e6);
}

// The formulations' products on one mesh: matrix-free (the kernel's sweeps, the nodal pressure
// fused into the second: docs/solver.md#nodal-averaged-product) and assembled, 1 and 2 threads.
void section_formulations(const TetMesh& m, const std::string& name, int reps, Csv& csv) {
  std::printf("\nformulations, corotational K*x on %s (%zu tets), median of %d: matrix-free and assembled (CSR)\n",
              name.c_str(), m.num_tets(), reps);
  std::printf("%16s %3s %10s %10s %12s %10s\n", "formulation", "thr", "mf ms", "csr ms", "mf/standard", "csr/mf");
  std::mt19937 rng(2);
  std::normal_distribution<double> nd;
  double standard_mf[3] = {0, 0, 0};
  for (Formulation f : {Formulation::Standard, Formulation::NodalAveraged, Formulation::EdgeSmoothed}) {
    FemModel model(m, MaterialTable(Material{3000, 0.45, 1000}), FemKind::Corotational, f);
    Eigen::VectorXd u(model.rows()), x(model.rows()), y, y2;
    const double scale = 0.01 * m.total_volume() / std::max(1.0, double(m.num_tets()));
    for (Eigen::Index i = 0; i < u.size(); ++i) u[i] = std::cbrt(scale) * nd(rng), x[i] = nd(rng);
    model.update_rotations(u);
    AssembledStiffness as(model);
    for (int threads : {1, 2}) {
      tbb::global_control gc(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
      const double mf = time_ms(reps, [&] { model.multiply(x, y); });
      const double csr = time_ms(reps, [&] { as.multiply(x, y2); });
      if (f == Formulation::Standard) standard_mf[threads] = mf;
      std::printf("%16s %3d %10.3f %10.3f %12.2f %10.2f\n", std::string(formulation_name(f)).c_str(), threads, mf, csr,
                  mf / standard_mf[threads], csr / mf);
      csv.row(std::string("formulation-") + std::string(formulation_name(f)), double(m.num_tets()), double(m.num_vertices()),
              threads, mf, csr, 0, csr / mf, 0, 0, 0, 0, 0, 0, 0, double(as.matrix().nonZeros()), 0, mf / standard_mf[threads]);
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  Args args(argc, argv);
  const auto sizes = args.list("--sizes", "10000,100000,1000000");
  const int reps = int(args.num("--reps", 7));
  Csv csv(args.get("--out", "."), "fem_kx.csv",
          "kind,tets,vertices,threads,matrix_free_ms,assembled_ms,eigen_spmv_ms,ratio_assembled_over_mf,mf_gbs,"
          "assembled_gbs,stream_gbs,mf_pct_bound,assembled_pct_bound,assembly_ms,model_build_ms,nnz,portable_mf_ms,"
          "ratio_assembled_over_portable");
  std::printf("K*x, median of %d; bandwidth bound from a STREAM triad measured in the same run\n", reps);
  std::printf("%6s %9s %3s %10s %10s %10s %8s %8s %8s %8s %10s %8s\n", "kind", "tets", "thr", "mf ms", "csr ms", "eigen ms",
              "csr/mf", "mf %bw", "csr %bw", "GB/s", "port. ms", "csr/port");
  std::vector<FemKind> kinds{FemKind::Linear};
  if (!args.flag("--linear-only")) kinds.push_back(FemKind::Corotational);
  for (double target : sizes)
    for (FemKind kind : kinds) {
    const bool corot = kind == FemKind::Corotational;
    const int n = std::max(1, int(std::lround(std::cbrt(target / 6))));
    TetMesh m = make_box(Vec3(1, 1, 1), {n, n, n});
    const double t_build0 = now_ms();
    FemModel model(m, MaterialTable(Material{}), kind);
    const double build_ms = now_ms() - t_build0;
    const double t_as0 = now_ms();
    AssembledStiffness as(model);
    const double assembly_ms = now_ms() - t_as0;
    std::mt19937 rng(1);
    std::normal_distribution<double> nd;
    Eigen::VectorXd x(model.rows()), y(model.rows()), y2(model.rows());
    for (Eigen::Index i = 0; i < x.size(); ++i) x[i] = nd(rng);
    if (corot) {  // rotations from a random displacement, so K_R is not K
      Eigen::VectorXd u(model.rows());
      for (Eigen::Index i = 0; i < u.size(); ++i) u[i] = 0.01 * nd(rng);
      model.update_rotations(u);
      as.rebuild();
    }
    // Minimal traffic per product. Matrix-free: per tet the packet data (B 72, V mu and V lambda
    // 16, vertex ids 16; the rotation's quaternion 32 for corotational); per vertex x read (24),
    // the padded y written and read back (64) and y written (24).
    // Assembled: values + column indices (12 per nonzero), row pointers, x and y.
    const double nt = double(m.num_tets()), nv = double(m.num_vertices());
    const double mf_bytes = nt * (72 + 16 + 16 + (corot ? 32 : 0)) + nv * (24 + 64 + 24);
    const double nnz = double(as.matrix().nonZeros());
    const double as_bytes = nnz * 12 + nv * 3 * 4 + nv * 2 * 24;
    for (int threads : {1, 2}) {
      tbb::global_control gc(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
      const double bw = stream_triad_gbs(5);
      const double mf = time_ms(reps, [&] { model.multiply(x, y); });
      const double csr = time_ms(reps, [&] { as.multiply(x, y2); });
      const double eig = time_ms(reps, [&] { y2.noalias() = as.matrix() * x; });
      model.set_kernel_simd(false);  // the portable path, as on CPUs without AVX2
      const double port = time_ms(reps, [&] { model.multiply(x, y); });
      model.set_kernel_simd(true);
      const double mf_gbs = mf_bytes / (mf * 1e6), as_gbs = as_bytes / (csr * 1e6);
      std::printf("%6s %9.0f %3d %10.3f %10.3f %10.3f %8.2f %7.1f%% %7.1f%% %8.1f %10.3f %8.2f\n", corot ? "corot" : "linear", nt,
                  threads, mf, csr, eig, csr / mf, 100 * mf_gbs / bw, 100 * as_gbs / bw, bw, port, csr / port);
      csv.row(corot ? "corotational" : "linear", nt, nv, threads, mf, csr, eig, csr / mf, mf_gbs, as_gbs, bw, 100 * mf_gbs / bw, 100 * as_gbs / bw,
              assembly_ms, build_ms, nnz, port, csr / port);
    }
    std::printf("          (model build %.0f ms, assembly %.0f ms, %.1fM nonzeros = %.0f MB)\n", build_ms, assembly_ms,
                nnz / 1e6, nnz * 12 / 1e6);
  }
  const std::string organ = args.get("--organ", "");
  if (!organ.empty()) section_formulations(read_tet_mesh(organ), organ, reps, csv);
  else section_formulations(make_box(Vec3(2, 1, 1), {33, 16, 8}), "a box", reps, csv);
  std::printf("ratio > 1: matrix-free is faster than the assembled product. CSV: %s\n", csv.path().c_str());
  return 0;
}
