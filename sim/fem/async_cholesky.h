#pragma once
// The strong preconditioner that survives cuts: a sparse Cholesky factorization of the system
// (K, or a M + c K) on its free unknowns, computed on a background thread from a snapshot of
// the model, and used by CG until a fresher one is ready (after Courtecuisse et al.'s
// asynchronous preconditioner in SOFA). A frame never waits for a factorization, except the
// very first one when `wait_for_first` is set.
//
// After a topology change the stale factor keeps preconditioning, mapped onto the new
// unknowns: vertex ids are stable across edits, so a surviving unknown maps to itself, and a
// vertex an edit added maps to its parents with the edit's interpolation weights (a cut's
// duplicate to the vertex it was split from), through a prolongation P. Added vertices, and
// those whose incident tets changed (stale factor rows), also get block-Jacobi, and so do
// unknowns the factor does not reach (not free at the snapshot).
// M^-1 = P F^-1 P^T + block-Jacobi on those is symmetric positive definite however
// stale F is, so plain CG stays correct; only the iteration count degrades until the fresh
// factor is adopted (at the start of a frame, then CG restarts).
//
// Corotational models (`rotate`): between factorizations the elements rotate, and K_R = R K R^T
// drifts away from the factor's snapshot mostly by those rotations. So the stale factor is
// used rotated: M^-1 = Q P F^-1 P^T Q^T, Q block-diagonal with one 3x3 rotation per vertex, the
// change of the vertex's rotation since the snapshot (the polar factor of the volume-weighted
// sum of its incident tets' R_now R_snapshot^T; an added vertex uses its first parent's). Q is
// computed at each fresh CG start (setup(): O(vertices + tets), parallel, one 3x3 polar per
// vertex, like the per-tet rotation update the frame already does), never per iteration, and
// it stays fixed during a solve. Q orthogonal keeps M^-1 symmetric positive definite.
//
// Factorization: CHOLMOD's supernodal LL^T when built with it, else Eigen's SimplicialLDLT.
#include <atomic>
#include <cstdint>
#include <future>
#include <memory>
#include <unordered_map>
#include <vector>

#include "mesh/topology_change.h"
#include "sim/fem/fem_model.h"
#include "sim/linalg/preconditioner.h"

namespace incise {

struct AsyncCholeskyOptions {
  bool background = true;          // factorize on a thread (false: in frame(), for tests/benchmarks)
  bool wait_for_first = true;      // the first factor is waited for (no factor to fall back on yet)
  int refactor_iterations = 10;    // a frame needing more CG iterations asks for a fresh factor
  std::size_t max_unknowns = 150000;  // above this many free unknowns no factor is built (the multigrid
                                      // with settle_with_amg, else block-Jacobi)
  bool rotate = true;              // corotational: rotate the stale factor by the vertices' rotation change
  // > 0: while the topology changes (a blade moving), precondition with block-Jacobi alone and
  // start no factorization; once `settle_frames` frames passed without a change, factorize,
  // and use the factor again when one of the settled topology lands. 0: keep preconditioning
  // with the stale factor (with block-Jacobi corrections) and refactor after every change.
  // On the organ cut scene (bench_fem_precond --only cut-scene) the stale factor took several
  // times the frame of block-Jacobi while the blade moves (fewer iterations, each a triangular
  // solve), and a core stays busy refactoring; hence the default (docs/solver.md#behind-the-constants).
  int settle_frames = 3;
  // While the blade moves (settle_frames) and before the first factor lands, precondition with
  // the aggregation multigrid (sim/fem/aggregation_amg.h) instead of block-Jacobi; the FEM frame
  // driver makes it and attaches it (set_moving). Block-Jacobi stays the budget's cheaper one.
  // On by default: it shortened the organ cut scene's frames through the cut (docs/solver.md#behind-the-constants);
  // between cuts nothing changes.
  bool settle_with_amg = true;
};

class AsyncCholesky : public CgPreconditioner {
public:
  explicit AsyncCholesky(const FemModel& model, const AsyncCholeskyOptions& options = {});
  ~AsyncCholesky() override;  // stops a running factorization at its next phase and waits for it

  // Between frames, before the solve: adopts a finished factor, and starts a new one when stale
  // (see mark_stale, apply) or the last frame needed more than refactor_iterations. The system
  // is a M + c K on the `free` unknowns. Returns true when a new factor was adopted.
  bool frame(const std::vector<std::uint8_t>& free, double mass_coeff, double stiffness_coeff, int last_iterations);
  // The constraint set changed: the next frame starts a fresh factorization.
  void mark_stale();
  // Marks the vertices an edit batch added or removed as not covered (O(size of the change))
  // and asks for a fresh factor.
  void apply(const TopologyChange& change);

  void setup(const LinearOperator& a, const std::vector<std::uint8_t>* free) override;
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const override;
  std::uint64_t version() const override { return version_; }
  // Block-Jacobi: for budgets that cannot afford a triangular solve.
  CgPreconditioner* cheaper() override { return &fallback_; }
  // What preconditions instead of block-Jacobi while there is no factor of the current
  // topology in use (settling, or before the first factor): not owned, nullptr: block-Jacobi.
  void set_moving(CgPreconditioner* pc) { moving_ = pc; }
  // The moving one's, while it is the one in use (a multigrid patch after a cut is due or not).
  double next_setup_ms() const override { return use_moving() ? moving_->next_setup_ms() : -1; }

  bool has_factor() const;
  // Whether the moving preconditioner (the multigrid) preconditions now: no factor of the
  // current topology, or none at all (above max_unknowns).
  bool uses_multigrid() const { return use_moving(); }
  bool settling() const { return settling_; }  // block-Jacobi alone (settle_frames policy)
  bool factorizing() const { return job_.valid(); }
  int factorizations() const { return factorizations_; }  // adopted so far
  // Started on the background thread (the lowest priority) so far; a factor the frame waits
  // for (the first, with wait_for_first) is made on the frame's own thread instead.
  int background_factorizations() const { return background_factorizations_; }
  double last_factorize_ms() const { return last_ms_; }    // snapshot-to-factor time of the last adopted one

  struct Factor;  // the factorization and its unknown map (in the .cpp)

private:
  void start(const std::vector<std::uint8_t>& free, double a, double c);
  void adopt();
  void update_rotation_change();  // q_ from the model's current rotations and snap_rot_
  // The moving preconditioner is in use: no factor of the current topology (and none at all
  // above max_unknowns: there the multigrid takes every frame; docs/solver.md#what-each-core-buys).
  bool use_moving() const { return moving_ && (too_large_ || !factor_ || settling_); }

  const FemModel* model_;
  AsyncCholeskyOptions opt_;
  std::shared_ptr<Factor> factor_;
  std::future<std::shared_ptr<Factor>> job_;
  // Set by the destructor: the running job stops at its next phase (assembly, ordering, numeric
  // factor) instead of finishing a factor nobody will use.
  std::shared_ptr<std::atomic<bool>> cancel_;
  void map_added(const VertexOrigin& o);  // P's row of an added vertex, from its parents

  std::vector<std::uint32_t> changed_since_snapshot_;  // vertices to uncover when the job lands
  std::vector<VertexOrigin> added_since_snapshot_;     // replayed onto the fresh factor's P
  // P: added vertex -> (covered vertex, weight) pairs.
  std::unordered_map<std::uint32_t, std::vector<std::pair<std::uint32_t, double>>> mapped_;
  std::vector<std::uint8_t> uncovered_;                // per vertex, for the current factor
  std::vector<std::uint32_t> touched_;                 // covered vertices whose rows an edit changed, once each
  std::vector<std::uint8_t> touched_mark_;             // per vertex: in touched_
  std::vector<std::uint32_t> touched_since_snapshot_;  // their rows are stale in the job's factor too
  void touch(std::uint32_t v);
  bool too_large_ = false, stale_ = false, failed_ = false;
  // settle_frames policy: frames since the last topology change, change batches so far, the
  // batch count at the snapshot of the running job and of the current factor.
  int quiet_frames_ = 1 << 30;
  std::uint64_t changes_ = 0, job_changes_ = 0, factor_changes_ = 0;
  bool settling_ = false;
  double snapshot_a_ = -1, snapshot_c_ = -1;
  BlockJacobi fallback_;
  CgPreconditioner* moving_ = nullptr;
  const std::vector<std::uint8_t>* free_ = nullptr;
  std::uint64_t version_ = 0;
  int factorizations_ = 0, background_factorizations_ = 0;
  double last_ms_ = 0;
  mutable Eigen::VectorXd rf_, zf_;
  // Rotation: per-tet rotations at the snapshot of the current factor (pending_: of the job),
  // and per vertex the rotation change q_ (empty: no rotation).
  std::shared_ptr<const std::vector<Eigen::Matrix3d>> snap_rot_, pending_rot_;
  std::vector<Eigen::Matrix3d> q_;
};

}  // namespace incise
