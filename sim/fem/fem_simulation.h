#pragma once
// FemSimulation: one frame at a time of the FEM model on a (possibly changing) TetMesh.
//
// Static mode (default) solves K u = f each frame; dynamic mode takes one backward-Euler step
//   ((1 + dt*damping) M + dt^2 K) v' = M v + dt (f_ext + f_int(u)),  u' = u + dt v'
// with the same solvers. Corotational models re-linearize about the current displacement
// (`nonlinear_iterations` times per static frame), so repeated frames converge to the
// corotational equilibrium.
//
// Solvers: CG on the matrix-free model or on the assembled matrix (same CG, same stats), or
// the direct LDL^T reference. CG is warm-started from the previous frame (static frames: with
// a prediction extrapolated from the last five, see sim/fem/warm_start.h) and may stop on a
// wall-clock budget; the approximate solution is kept, and when nothing changed by the next
// frame (loads, constraints, topology; corotational rotations are not refreshed while such a
// solve is pending) CG resumes it, so budgeted frames add up to one uninterrupted solve.
//
// Constraints are per vertex and axis: fix() (zero displacement) or prescribe() (a
// displacement) hold all three components, constrain() chosen ones (a roller: a symmetry plane
// or a plane-strain face); they enter CG by projection and the right-hand side. A static solve
// first checks, per face-connected part of the mesh, that the constrained components block all
// six rigid motions (three translations, three rotations), and throws InvalidArgument naming the
// part otherwise (the check is O(mesh), run only after the
// constraint set changed, never after apply(): call check_constraints() after a cut if wanted).
//
// Topology changes: apply(change) after every mesh edit batch. Per-tet data, diagonal and
// masses are updated locally; new vertices get interpolated displacement and velocity, and are
// constrained (with interpolated values) when all their parents are.
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mesh/change_follower.h"
#include "mesh/tet_mesh.h"
#include "sim/fem/aggregation_amg.h"
#include "sim/fem/async_cholesky.h"
#include "sim/linalg/cg_solver.h"
#include "sim/fem/fem_model.h"
#include "sim/fem/formulation.h"
#include "sim/material.h"
#include "sim/fem/warm_start.h"

namespace incise {

class AssembledStiffness;
class AsyncCholesky;
class DirectSolver;
class MixedSolver;
class QuadraticSolver;
class PetscSolver;

enum class SolverMethod { Cg, Direct };
// Petsc: the system assembled into a distributed PETSc matrix and solved by PETSc's KSP (CG with
// GAMG by default) instead of incise's CG; sim/petsc/petsc_solver.h, docs/solver.md#petsc-more-than-one-machine.
enum class StiffnessBackend { MatrixFree, Assembled, Petsc };

struct FemSimulationOptions {
  FemKind kind = FemKind::Linear;                       // Linear or Corotational elements
  // Standard, NodalAveraged (no volumetric locking as Poisson's ratio nears 0.5; same solvers),
  // or Mixed: displacement and pressure (sim/fem/mixed_solver.h), solved by MINRES (CG's tolerance,
  // cap and budget; its displacement block preconditioned by the Cholesky factor, the multigrid,
  // or block-Jacobi for the others) or by SparseLU (method Direct); Poisson's ratio 0.5 allowed.
  // Quadratic / MixedQuadratic: 10-node tets (sim/fem/quadratic_solver.h), assembled and solved to
  // tolerance each frame (no budget, no warm-start prediction; a change rebuilds them).
  Formulation formulation = Formulation::Standard;
  SolverMethod method = SolverMethod::Cg;               // Direct: SimplicialLDLT reference
  StiffnessBackend backend = StiffnessBackend::MatrixFree;  // operator CG multiplies with, or Petsc
  std::string petsc_options;                            // Petsc: PETSc options ("-ksp_type minres ...")
  // tolerance, cap, budget, preconditioner: the asynchronous Cholesky, as in scenes (the
  // fastest measured, docs/solver.md; the multigrid above AsyncCholeskyOptions::max_unknowns).
  CgOptions cg{.preconditioner = Preconditioner::Cholesky};
  AsyncCholeskyOptions cholesky;                        // for cg.preconditioner == Cholesky
  AggregationAmgOptions amg;                            // for cg.preconditioner == Amg
  bool warm_start = true;                               // start CG from the previous frame
  bool predict = true;                                  // static warm start extrapolates the last frames
  bool dynamic = false;                                 // backward Euler instead of static
  double dt = 0.01;                                     // dynamic time step [s]
  double damping = 0;                                   // mass-proportional damping [1/s]
  int nonlinear_iterations = 1;                         // corotational re-linearizations per static frame
  // With cg.budget_ms: the corotational rotations may take at most this share of the budget
  // (measured per packet of tets); the tets that do not fit are refreshed in the next frames,
  // in turn (FemModel::update_rotations_partial; docs/solver.md#behind-the-constants).
  double relinearize_share = 0.5;
  // Corotational: hold tets whose volume ratio falls below inversion_barrier.j_min (0: off;
  // sim/fem/inversion_barrier.h, docs/solver.md#inversion-barrier-inversion_barrier-in-scenes).
  InversionBarrierOptions inversion_barrier;
  Vec3 gravity = Vec3::Zero();                          // body acceleration [m/s^2]
  bool check_rigid_modes = true;                        // refuse under-constrained static solves
};

// Statistics of one frame (sums over the corotational re-linearizations).
struct FrameStats {
  int iterations = 0;
  int products = 0;                      // all operator products of the solves (CG: iterations + starts)
  double relative_residual = 0;
  double initial_relative_residual = 0;  // first solve of the frame, at its start point
  double guess_relative_residual = 0;    // same, before the prediction (at the last solution)
  bool resumed = false;                  // CG continued the previous frame's interrupted solve
  double solve_ms = 0;
  double preconditioner_setup_ms = 0;    // of solve_ms: the preconditioner's setup (block-Jacobi blocks, a multigrid rebuild)
  double frame_ms = 0;                   // the whole step(): rotations, right-hand side, solves
  // Before the first solve started: factor adoption, rotations, right-hand side. A budgeted
  // frame's solve gets only what this left of budget_ms (at least one iteration runs).
  double setup_ms = 0;
  double outside_ms = 0;                 // spent before step() on this frame (its argument), taken off the budget
  bool budget_exhausted = false;
  bool cheaper_preconditioner = false;   // the budget could not afford the preconditioner (CG used its cheaper one)
  double relinearized = 1;               // corotational: share of the tets whose rotations this frame refreshed
  SolveInfo info = SolveInfo::Success;
  std::string message;
};

class FemSimulation {
public:
  FemSimulation(const TetMesh& mesh, const MaterialTable& materials, const FemSimulationOptions& options = {});
  ~FemSimulation();

  // ---- constraints and loads (by vertex) ------------------------------------------
  void fix(VertexId v) { prescribe(v, Vec3::Zero()); }
  void prescribe(VertexId v, const Vec3& displacement) { constrain(v, kAllAxes, displacement); }
  // Holds the components in `axes` (bit 0: x, 1: y, 2: z) at those of `displacement`, in
  // addition to any already held; the other components stay as they were.
  void constrain(VertexId v, unsigned axes, const Vec3& displacement = Vec3::Zero());
  void release(VertexId v);
  static constexpr unsigned kAllAxes = 7;
  bool is_constrained(VertexId v) const { return constrained_[v.idx()] != 0; }  // any component
  unsigned constrained_axes(VertexId v) const { return constrained_[v.idx()]; }
  void set_force(VertexId v, const Vec3& f) { f_ext_.segment<3>(3 * v.idx()) = f; }
  void add_force(VertexId v, const Vec3& f) { f_ext_.segment<3>(3 * v.idx()) += f; }
  void clear_forces() {
    f_ext_.setZero();
    qf_.setZero();
  }
  void set_gravity(const Vec3& g) { opt_.gravity = g; }

  // ---- frames ------------------------------------------------------------------------
  // One frame. Throws InvalidArgument when a static solve is under-constrained; a breakdown
  // (not positive definite, NaN/Inf in the solution or its residual) is returned in the stats
  // as NotPositiveDefinite or NumericalIssue with a message; the displacement keeps its last
  // finite value.
  // spent_ms: what this frame already spent before the solve (a cut step, the backends'
  // updates); it comes off cg.budget_ms, so a budget bounds the whole frame. When it exceeds
  // the budget the frame still runs one iteration (every frame progresses).
  const FrameStats& step(double spent_ms = 0);
  const FrameStats& last_stats() const { return stats_; }
  // The static solve's rigid-mode check on its own (O(mesh)); throws InvalidArgument.
  void check_constraints() const { check_rigid_modes(); }
  void reset_state();  // zero displacement and velocity

  // ---- topology ------------------------------------------------------------------------
  void apply(const TopologyChange& change);

  // ---- state (by VertexId; 3 per vertex) -----------------------------------------------
  const Eigen::VectorXd& displacement() const { return u_; }
  Eigen::VectorXd& displacement() { return u_; }
  const Eigen::VectorXd& velocity() const { return v_; }
  std::vector<Vec3> positions() const;                  // rest + displacement
  std::vector<double> von_mises() const;                // per TetId, current state
  const std::vector<std::uint8_t>& free_mask() const { return free_; }

  // The asynchronous factorization behind Preconditioner::Cholesky (nullptr until used).
  const AsyncCholesky* cholesky() const { return cholesky_.get(); }
  // The aggregation multigrid behind Preconditioner::Amg (nullptr until used).
  const AggregationAmg* amg() const { return amg_.get(); }
  // The mixed formulation's solver (nullptr for the others); its pressure() is per vertex slot.
  const MixedSolver* mixed() const { return mixed_.get(); }
  // Quadratic and MixedQuadratic: the 10-node solver (nullptr for the others) and the displacement
  // of every P2 node (its p2() numbering: the vertex slots, then the mid-edge nodes); displacement()
  // holds the corners'. Loads set by vertex act on the corner nodes; gravity and
  // add_face_traction() are consistent over the 10 / 6 nodes.
  const QuadraticSolver* quadratic() const { return quadratic_.get(); }
  const Eigen::VectorXd& quadratic_displacement() const { return qu_; }
  // A uniform traction t [Pa] on the boundary triangle (a, b, c), added to the external forces
  // until clear_forces(): area / 3 per corner on linear tets, the 6-node triangle's consistent
  // load (area / 3 per mid-edge node) on quadratic ones.
  void add_face_traction(VertexId a, VertexId b, VertexId c, const Vec3& t);
  // The PETSc solver behind StiffnessBackend::Petsc (nullptr until the first solve).
  const PetscSolver* petsc() const { return petsc_.get(); }
  FemModel& model() { return model_; }
  const FemModel& model() const { return model_; }
  FemSimulationOptions& options() { return opt_; }
  ConjugateGradient& cg() { return cg_; }

private:
  std::chrono::steady_clock::time_point frame_start_;  // of the current step()
  double frame_budget_ms_ = 0;  // this frame's: cg.budget_ms less what the caller spent before step(); 0: none
  void grow();
  void update_free(std::uint32_t v);
  void check_rigid_modes() const;
  void body_and_external_forces(Eigen::VectorXd& b) const;
  void solve_system(const LinearOperator& op, double mass_coeff, double stiffness_coeff, const Eigen::VectorXd& b,
                    Eigen::VectorXd& x, double budget_ms, FrameStats& st, std::span<const Eigen::VectorXd> prediction);
  void check_finite(const Eigen::VectorXd& x, FrameStats& st) const;
  void relinearize();
  void static_rhs_and_guess();
  void step_mixed(std::chrono::steady_clock::time_point t0);
  void step_quadratic();  // sim/fem/fem_simulation_quadratic.cpp
  void make_quadratic();

  const TetMesh* mesh_;
  ChangeFollower follower_;  // apply() takes the mesh's changes in order, each once
  FemSimulationOptions opt_;
  FemModel model_;
  std::unique_ptr<AssembledStiffness> assembled_;
  std::unique_ptr<DirectSolver> direct_;
  bool assembled_dirty_ = true, direct_dirty_ = true, rigid_dirty_ = true;
  double direct_mass_coeff_ = -1, direct_stiffness_coeff_ = -1;
  ConjugateGradient cg_;
  // The system CG runs on (K, or a M + c K); rebuilt, and CG re-bound, when system_dirty_.
  std::unique_ptr<LinearOperator> system_;
  const LinearOperator* system_k_ = nullptr;
  double system_a_ = -1, system_c_ = -1;
  bool system_dirty_ = true;
  bool changed_since_frame_ = false;  // a topology change since the last step(): no prediction
  WarmStartPredictor predictor_;
  std::unique_ptr<AsyncCholesky> cholesky_;  // Preconditioner::Cholesky: built on first use
  std::unique_ptr<AggregationAmg> amg_;      // Preconditioner::Amg: built on first use
  std::unique_ptr<MixedSolver> mixed_;       // Formulation::Mixed: it solves every frame
  std::unique_ptr<PetscSolver> petsc_;       // StiffnessBackend::Petsc: built on first use
  bool uses_own_cg() const { return opt_.method == SolverMethod::Cg && opt_.backend != StiffnessBackend::Petsc; }
  void solve_petsc(const LinearOperator& op, double a, double c, const Eigen::VectorXd& b, Eigen::VectorXd& x,
                   FrameStats& st);
  bool mixed_pending_ = false;               // the last mixed solve ran out of budget
  std::unique_ptr<QuadraticSolver> quadratic_;  // Formulation::Quadratic / MixedQuadratic
  Eigen::VectorXd qu_, qv_, qf_;             // per P2 unknown: displacement, velocity, face loads
  MaterialTable materials_;                  // kept for the quadratic solver's rebuild after a change
  Eigen::VectorXd b_rot_;              // corotational right-hand side term
  double relinearize_ms_per_packet_ = 0;  // measured (running mean) cost of refreshing one packet's rotations
  std::size_t relinearize_cursor_ = 0;    // the next packet a partial refresh starts at
  std::vector<Eigen::VectorXd> d_;     // prediction directions

  Eigen::VectorXd u_, v_, f_ext_, target_;  // target_: prescribed displacement per unknown
  std::vector<std::uint8_t> constrained_;   // per vertex: the held axes (bit 0: x, 1: y, 2: z)
  std::vector<std::uint8_t> free_;          // per unknown: CG may change it
  FrameStats stats_;
  Eigen::VectorXd b_, x_, tmp_;
};

}  // namespace incise
