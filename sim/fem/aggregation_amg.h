#pragma once
// Two-level aggregation multigrid for 3D elasticity (FEM K, or a M + c K), a CG
// preconditioner whose iteration count stays low through cuts, at a few products per
// application.
//
// Coarse space: the vertices are grouped into aggregates (sim/linalg/vertex_aggregation.h: greedy, on
// the mesh's current connectivity, so a cut separates aggregates), and each aggregate carries
// the six rigid-body modes of its vertices (3 translations, 3 rotations about its centroid, at
// rest positions), orthonormalized per aggregate; modes an aggregate cannot carry (a single
// vertex, collinear vertices) are dropped. That is the tentative (unsmoothed) prolongator P,
// one 3x6 block per vertex. The coarse operator A_c = P^T A P is assembled element by element
// from the model's per-tet data (its current rotations, as K x uses them) straight into 6x6
// blocks per pair of aggregates, and factored directly (sim/linalg/block_cholesky.h: sparse LL^T on
// the aggregate graph, for a few hundred aggregates; CHOLMOD above; ~6 unknowns per aggregate). Kept (fixed, prescribed) unknowns have zero rows in P, like block-Jacobi's.
//
// Application, z = M^-1 r:
//  - additive (default): z = S r + P A_c^-1 P^T r, no product; SPD for any SPD A_c. About
//    twice the iterations of the multiplicative cycle at a third of the cost each; its frame
//    on the organ cut scene was never slower (docs/solver.md#what-the-frame-through-a-cut-is-made-of).
//  - multiplicative: a symmetric two-level V-cycle, damped block-Jacobi S before and after the
//    coarse correction: z = w S r; z += P A_c^-1 P^T (r - A z); z += w S (r - A z). Two
//    products A x per application. SPD when w < 2 / lambda_max(S A) (w is 4/3 over an
//    estimate of lambda_max made at the first build, with a 10% margin) and A_c SPD, whatever
//    A_c is the exact Galerkin operator of A or a stale one.
//
// Through changes: after a topology change (apply) the hierarchy is patched at the next CG
// fresh start: the aggregates holding a vertex the change names are dissolved, their vertices
// and the new ones re-aggregated, P and the rows of A_c recomputed for the new aggregates only,
// and the coarse matrix refactored (O(change) for the fine-level work, plus the coarse matrix
// and its factorization, O(coarse); two O(vertices) flag arrays are cleared; a patch whose A_c
// is not positive definite, rows of different frames' rotations side by side, is replaced by a
// full rebuild). A constraint change (mark_stale) or a new system scaling (frame) rebuilds;
// so does, for corotational models, a frame that needed more than `rebuild_iterations`
// iterations (off by default: between cuts A_c keeps its rotations, the smoother reads the
// current blocks). `topology_rebuild_iterations` > 0 instead keeps the stale hierarchy after a
// change until a frame needs that many iterations (slower than patching: bench_fem_precond
// --only cut-scene, "amg lazy"). Patches and
// builds run in setup(), so CG's budget planning sees them (next_setup_ms() says whether one
// is due) and a budget that cannot afford one uses cheaper() (block-Jacobi) for the frame.
// Nodal-averaged models (sim/fem/formulation.h): A_c also carries the Galerkin product of the
// volumetric term, sum_a kappa_a V_a (B_a P)^T (B_a P), summed into the fine rows from the
// model's rows of B. A cut changes the rows of B of the vertices it names (their tets and V_a
// changed), and K's coupling between two surviving aggregates with them: a patch keeps each
// vertex's last B_a P and exchanges the named vertices' terms in those blocks, O(change).
// Costs and iterations on the organ cut scene: docs/solver.md.
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "mesh/topology_change.h"
#include "sim/fem/fem_model.h"
#include "sim/linalg/preconditioner.h"
#include "sim/linalg/vertex_aggregation.h"

namespace incise {

struct AggregationAmgOptions {
  enum class Cycle { Multiplicative, Additive };
  Cycle cycle = Cycle::Additive;
  // Phase-1 aggregates: the root and `ring` rings of neighbours. 2: larger aggregates and a
  // coarse level a few times smaller than ring 1's, whose factor costs less than the extra
  // iterations it brings (figures: docs/solver.md#the-aggregation-multigrid-amg). 0 (the
  // default): 2, or 3 where ring 2 leaves more than `ring3_above` aggregates: on large meshes
  // the coarse factor, refactored after every cut step, outgrows the frame, and a coarser
  // level costs fewer milliseconds than its extra iterations (docs/solver.md#what-each-core-buys).
  int ring = 0;
  int ring3_above = 1100;
  bool rotations = true;            // rotational modes in the coarse space (false: translations only)
  double smoother_weight = 0;       // w of the damped block-Jacobi; 0: 4/3 / lambda_max estimated
  int rebuild_iterations = 1 << 30;  // corotational: a frame above this many iterations rebuilds A_c
  // After a topology change: rebuild at the next solve (0), or keep the stale hierarchy until a
  // frame needs more than this many iterations (> 0). The stale one leaves the vertices a cut
  // added to the smoother, and its A_c still couples across the cut: SPD all the same.
  int topology_rebuild_iterations = 0;
  // The coarse factor: the block Cholesky (sim/linalg/block_cholesky.h) up to this many aggregates
  // when they carry about six modes each, a general sparse factor (CHOLMOD) otherwise; why
  // this bound: docs/solver.md#behind-the-constants.
  int block_factor_aggregates = 1100;
};

struct AmgBuildStats {
  double aggregate_ms = 0, prolongator_ms = 0, coarse_ms = 0, factor_ms = 0, total_ms = 0;
  std::size_t aggregates = 0, coarse_unknowns = 0, coarse_nonzeros = 0, factor_nonzeros = 0;
  bool factor_ok = false;
  bool block_factor = false;           // the block Cholesky factored A_c (not the general one)
  std::size_t patched_aggregates = 0;  // a patch: the aggregates it made
  int ring = 0;                        // the aggregates' ring (AggregationAmgOptions::ring, chosen)
};

class AggregationAmg : public CgPreconditioner {
public:
  explicit AggregationAmg(const FemModel& model, const AggregationAmgOptions& options = {});
  ~AggregationAmg() override;

  // Before a frame's solves: the system is a M + c K (a new scaling rebuilds); `last_iterations`
  // of the previous frame may ask for a rebuild (rebuild_iterations).
  void frame(double mass_coeff, double stiffness_coeff, int last_iterations);
  void apply(const TopologyChange& change);  // the next setup() rebuilds
  void mark_stale();                          // the constraint set changed: same

  void setup(const LinearOperator& a, const std::vector<std::uint8_t>* free) override;
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const override;
  std::uint64_t version() const override { return version_; }
  CgPreconditioner* cheaper() override { return &smoother_; }
  // The smoother's setup, plus the last patch's or build's cost when one is due.
  double next_setup_ms() const override;

  int builds() const { return builds_; }    // full builds
  int patches() const { return patches_; }  // local updates after topology changes
  int failed_patches() const { return failed_patches_; }  // A_c not positive definite: rebuilt
  const AmgBuildStats& build_stats() const { return stats_; }
  const VertexAggregates& aggregates() const { return agg_; }
  int ring() const { return ring_; }  // the ring the last build aggregated with
  double smoother_weight() const { return weight_; }

  struct Coarse;  // the coarse matrix and its factor (in the .cpp)

private:
  void build(const LinearOperator& a, const std::vector<std::uint8_t>* free);
  void patch(const LinearOperator& a, const std::vector<std::uint8_t>* free);
  void prolongator(const std::vector<std::uint32_t>& aggregates);  // centre, scale, T, P rows
  // Their rows_ of A_c; nodal-averaged, the B_a P of each vertex a whose smallest reached
  // aggregate at or above `keep_from` is among them are kept in vol_u_.
  void coarse_rows(const std::vector<std::uint32_t>& aggregates, std::size_t keep_from);
  // Nodal-averaged: the volumetric part of aggregate ai's row (scratch vectors per thread).
  void volumetric_rows(std::size_t ai, std::size_t keep_from,
                       std::vector<std::pair<std::int32_t, Eigen::Matrix<double, 6, 6>>>& row,
                       std::vector<std::uint32_t>& arows,
                       std::vector<std::pair<std::uint32_t, Eigen::Vector3d>>& brow,
                       std::vector<std::pair<std::int32_t, Eigen::Matrix<double, 6, 1>>>& coarse_b);
  // B_a P, one 6-vector per aggregate the row of B reaches (brow: scratch).
  void coarse_b_row(std::uint32_t a, std::vector<std::pair<std::uint32_t, Eigen::Vector3d>>& brow,
                    std::vector<std::pair<std::int32_t, Eigen::Matrix<double, 6, 1>>>& out) const;
  // Nodal-averaged, in a patch: the pending vertices' volumetric terms between aggregates that
  // survive it (ids below `first`), the kept ones taken out (sign -1) or the current ones put
  // in and kept (sign +1).
  void exchange_volumetric(std::size_t first, double sign);
  void factor();                                                    // A_c from rows_, factored
  double estimate_lambda_max(const LinearOperator& a, const std::vector<std::uint8_t>* free) const;
  void project(Eigen::VectorXd& v) const;

  const FemModel* model_;
  AggregationAmgOptions opt_;
  double mass_coeff_ = 0, stiffness_coeff_ = 1;
  bool stale_ = true;
  bool topology_changed_ = false;  // since the last build (topology_rebuild_iterations > 0)
  std::uint64_t version_ = 0;
  int builds_ = 0, patches_ = 0, failed_patches_ = 0;
  double smoother_ms_ = 0, patch_ms_ = 0, build_ms_ = 0;  // last measured
  AmgBuildStats stats_;

  const LinearOperator* a_ = nullptr;
  const std::vector<std::uint8_t>* free_ = nullptr;
  BlockJacobi smoother_;
  double weight_ = 0;  // of the damped smoother (multiplicative cycle)

  VertexAggregates agg_;
  int ring_ = 2;  // chosen at a build (AggregationAmgOptions::ring), kept by its patches
  // Per aggregate: its centroid and scale (rigid modes of vertex v: B_v = [I | -[(x_v - c) / h]x]),
  // T (6 x k, zero-padded: Q = B T has orthonormal columns), k and its first coarse unknown.
  std::vector<Eigen::Vector3d> centre_;
  std::vector<double> scale_;
  std::vector<Eigen::Matrix<double, 6, 6>> t_;
  std::vector<int> modes_;
  // Per vertex slot: its position scaled in its aggregate ((x - c) / h), and its 3x6 block of P
  // (columns beyond its aggregate's k are zero).
  std::vector<Eigen::Vector3d> pos_;
  std::vector<Eigen::Matrix<double, 3, 6>> p_;
  // Per aggregate: its row of A_c, (aggregate, k_a x k_b block in the top-left of a 6x6).
  std::vector<std::vector<std::pair<std::int32_t, Eigen::Matrix<double, 6, 6>>>> rows_;
  // Nodal-averaged: per vertex a, the B_a P (one 6-vector per aggregate it reaches, without the
  // system's stiffness coefficient) whose term c (B_a P)^T (B_a P) A_c holds, so that a patch
  // can take it out where a cut changed a's row of B.
  std::vector<std::vector<std::pair<std::int32_t, Eigen::Matrix<double, 6, 1>>>> vol_u_;
  std::vector<std::uint32_t> pending_;  // vertices named by changes since the last build/patch
  std::vector<std::uint8_t> eligible_;   // patch(): per vertex, all zero between patches
  std::unique_ptr<Coarse> coarse_;

  mutable Eigen::VectorXd t1_, t2_;
  mutable std::vector<Eigen::Matrix<double, 6, 1>> rc_;  // the coarse vector, per aggregate
};

}  // namespace incise
