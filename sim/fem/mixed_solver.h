#pragma once
// MixedSolver: linear or corotational elasticity in displacement u and a vertex pressure p
// (stabilized equal-order P1-P1), valid up to and including Poisson's ratio 0.5.
//
// Why: standard linear tets lock as nu -> 0.5 (one volume constraint per tet, nearly as many
// tets as unknowns) and lambda = inf at 0.5. Here the volumetric part is carried by p:
//   sigma = 2 mu eps(u) - p I,    div u + p / lambda = 0   (1/lambda = 0 at nu = 0.5),
// P1 pressures are stabilized by Bochev-Dohrmann polynomial projection
//   S = sum_t (1/mu_t) int_t (p - Pi0 p)(q - Pi0 q)   (Pi0: the tet's mean; S p = 0 for constant p),
// and the symmetric saddle-point system (pressure rows negated so it is symmetric)
//   [ K_mu   -B^T ] [u]   [f + b_R]
//   [ -B     -C   ] [p] = [  c_R  ],   C = S + M_p / lambda (consistent P1 mass),
// with K_mu the standard element at lambda = 0 (a FemModel on mu' = mu, lambda' = 0),
// B_{ij} = int_t N_i (R_t grad N_j)^T (the divergence in the tet's rotated frame), and, for
// corotational tets, the constant parts of the rotated strain on the right: b_R as FemModel's,
// c_R_i = sum_t V_t/4 (tr R_t - 3).
//
// Solver: preconditioned MINRES with the SPD block-diagonal preconditioner diag(P_u, P_p):
// P_u the aggregation multigrid (or block-Jacobi) of K_mu, P_p the lumped pressure mass
// scaled by (1/mu + 1/lambda) per tet (spectrally equivalent to the Schur complement
// B K_mu^-1 B^T + C). MINRES needs an SPD preconditioner, which both P_u choices are.
// Relative residual: ||r||_{P^-1} / ||b_eff||_{P^-1}, in the preconditioner's norm (u and p
// rows have different units; this norm weighs them consistently), b_eff the right-hand side
// with the prescribed values moved over (independent of the guess, as in ConjugateGradient).
// A wall-clock budget stops the iteration with its last iterate (MINRES's residual is
// monotone: the last is the best); the next solve() with the same loads, constraints and
// operator, from the u it returned, resumes the same Krylov iteration (budgeted calls add up
// to one uninterrupted solve); anything else starts afresh from u and the kept pressure.
// `direct`: the assembled saddle-point matrix factored by SparseLU (it is symmetric but
// indefinite, and at nu = 0.5 C is only semidefinite: not quasi-definite, so no LDL^T).
//
// Unknowns follow FemModel: displacement of vertex v at 3v..3v+2 over 3 * vertex_slots(),
// pressure of v at v over vertex_slots(). Slots without tets have zero rows and stay 0.
// Constraints per displacement unknown: `free` (1 = solved for, 0 = kept at the value u holds),
// so rollers (one component fixed) are a single 0.
// Local updates: apply(change) after every edit batch: the FemModel updates itself, this
// recomputes the rotated gradients of the added tets, the pressure preconditioner of the
// touched vertices, and interpolates the kept pressure onto added vertices.
#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "mesh/tet_mesh.h"
#include "sim/fem/aggregation_amg.h"
#include "sim/fem/async_cholesky.h"
#include "sim/fem/fem_model.h"
#include "sim/material.h"
#include "sim/linalg/preconditioner.h"

namespace incise {

// Materials per label like MaterialTable, but Poisson's ratio may be 0.5 (MaterialTable rejects
// it: the standard model is singular there). Implicit from a MaterialTable.
class MixedMaterials {
public:
  MixedMaterials() = default;
  MixedMaterials(const MaterialTable& table);  // NOLINT: implicit on purpose
  explicit MixedMaterials(const Material& fallback) { set_default(fallback); }
  void set_default(const Material& m);  // throws InvalidArgument for nu outside [0, 0.5]
  void set(int label, const Material& m);
  const Material& get(int label) const;  // throws InvalidArgument for an unknown label without default
  // mu' = mu, lambda' = 0 per label (young' = 2 mu, poisson' = 0): the K_mu model's table.
  MaterialTable deviatoric_table() const;

private:
  Material default_;
  bool has_default_ = true;
  std::unordered_map<int, Material> by_label_;
};

// 1 / lambda of a material, capped for nu -> 0 (lambda -> 0: p -> 0) at 1e8 / mu.
double inverse_lambda(const Material& m);

// The displacement block's preconditioner. Cholesky: the asynchronous factorization of
// sim/fem/async_cholesky.h (multigrid until the first factor lands when `cholesky.wait_for_first`
// is off, and while a blade moves): MINRES then needs about as many iterations as with an
// exact K_mu^-1 (27-36 on the clamped cantilever against 82-86 with the multigrid). Both the
// factor and the multigrid's coarse space leave out vertices with only some unknowns free
// (rollers): those get block-Jacobi alone, so on meshes with many rollers (the Lame cylinder)
// the multigrid is better and the factor worse than block-Jacobi.
enum class MixedPreconditioner { Amg, BlockJacobi, Cholesky };

struct MixedOptions {
  double tolerance = 1e-6;     // relative residual (see above)
  int max_iterations = 5000;   // per solve() call
  double budget_ms = 0;        // wall-clock budget per call; 0: none
  bool direct = false;         // SparseLU on the assembled system instead of MINRES
  // With direct: PETSc's MINRES and field split on the assembled system instead of SparseLU
  // (sim/petsc/petsc_saddle.h; to `tolerance`), with these PETSc options.
  bool petsc = false;
  std::string petsc_options;
  // K_mu's strain smoothed over edge domains (Formulation::MixedEdgeSmoothed; FemModel's
  // smooth_edges): linear tets' bending stiffness goes, the pressure coupling stays per tet.
  bool edge_smoothed = false;
  MixedPreconditioner preconditioner = MixedPreconditioner::Amg;
  AggregationAmgOptions amg;
  // For Cholesky (a budgeted solve never waits for the first factor). MINRES needs 20-40
  // iterations even with an exact K_mu^-1, so a refactorization is asked for above 100 (CG's 10
  // would refactor at every solve).
  AsyncCholeskyOptions cholesky = [] {
    AsyncCholeskyOptions o;
    o.refactor_iterations = 100;
    return o;
  }();
};

struct MixedStats {
  int iterations = 0;              // MINRES iterations of this call (one product each)
  int total_iterations = 0;        // since the last fresh start (a resumed solve adds up)
  double relative_residual = 0;    // at exit: the true residual, MINRES's estimate after a budgeted stop
  double initial_relative_residual = 0;
  bool converged = false;
  bool budget_exhausted = false;
  bool resumed = false;            // continued the previous interrupted iteration
  bool breakdown = false;          // NaN/Inf or a non-SPD preconditioner
  double solve_ms = 0;             // wall time of the call
  double setup_ms = 0;             // of it, the preconditioner's setup
};

class MixedSolver {
public:
  // O(mesh). The mesh must outlive the solver; throws like FemModel for bad tets.
  MixedSolver(const TetMesh& mesh, const MixedMaterials& materials, FemKind kind = FemKind::Linear,
              const MixedOptions& options = {});
  MixedSolver(TetMesh&&, const MixedMaterials&, FemKind = FemKind::Linear, const MixedOptions& = {}) = delete;
  ~MixedSolver();

  const MixedOptions& options() const { return opt_; }
  void set_options(const MixedOptions& o);  // restarts: an interrupted solve is not resumed
  // The wall-clock budget of the next solves alone (a frame gives what its setup left); keeps
  // an interrupted solve resumable.
  void set_budget_ms(double ms) { opt_.budget_ms = ms; }
  std::size_t vertex_slots() const { return model_.vertex_slots(); }
  std::size_t num_dofs() const { return model_.num_dofs(); }  // displacement unknowns
  // The K_mu model (mu per tet, lambda = 0): rotations, lumped mass, per-tet data. Its
  // von_mises(u) is the mixed stress's too: sigma = 2 mu eps - p I and -p I has no deviator.
  const FemModel& deviatoric_model() const { return model_; }

  // After every mesh edit batch. O(size of the change).
  void apply(const TopologyChange& change);
  // Corotational: per-tet rotations from u (no-op for Linear).
  void update_rotations(const Eigen::VectorXd& u);

  // Static solve (throws InvalidArgument unless the system is the static one). f: external force per displacement unknown (num_dofs()); free: per
  // displacement unknown; u: in, the prescribed values on kept unknowns and the start
  // elsewhere; out, the solution. The pressure is kept (pressure()) and warm-starts the next.
  MixedStats solve(const Eigen::VectorXd& f, const std::vector<std::uint8_t>& free, Eigen::VectorXd& u);

  // Dynamic steps (backward Euler, as FemSimulation's): the system becomes
  //   [ a M + c K_mu   -c B^T ] [v]   [b_u]
  //   [ -c B           -c C   ] [q] = [b_p]
  // (M the lumped mass). For velocity v' and end-of-step pressure p' (u' = u + dt v'):
  // a = 1 + dt damping, c = dt^2, q = p' / dt, b_u = M v + dt (f_ext + b_R - K_mu u),
  // b_p = dt (c_R + B u), where [K_mu u; -B u] = multiply([u; 0]) = multiply_static([u; 0]), and
  // b_R, c_R are right_hand_side(0). (0, 1): the static system (the default).
  // The pressure preconditioner adds c^2 diag(B diag(a M + c K)^-1 B^T) to c x the static one
  // when a > 0 (for small dt the Schur complement is mostly that Laplacian-like term).
  void set_system(double mass_coeff, double stiffness_coeff);
  double mass_coeff() const { return a_; }
  double stiffness_coeff() const { return c_; }
  // The current system with a full right-hand side b (num_dofs() + vertex_slots()); x: in, the
  // prescribed values on kept displacement unknowns and the start elsewhere (pressure slots
  // after the displacements); out, the solution. Does not touch pressure().
  MixedStats solve_system(const Eigen::VectorXd& b, const std::vector<std::uint8_t>& free, Eigen::VectorXd& x);

  const Eigen::VectorXd& pressure() const { return p_; }  // by vertex slot
  void set_pressure(const Eigen::VectorXd& p);
  // Per vertex slot: the pressure block of the preconditioner (lumped mass x (1/mu + 1/lambda)).
  const Eigen::VectorXd& pressure_diagonal() const { return pdiag_; }

  // y = A x for the current system (x = [u; p], 3n + n), no constraints: tests, the direct path.
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const;
  // The static system's product (a = 0, c = 1) whatever the current one: the dynamic
  // right-hand side's K_mu u and -B u.
  void multiply_static(const Eigen::VectorXd& x, Eigen::VectorXd& y) const;
  // The current system's matrix (4n x 4n), and the static right-hand side [f + b_R; c_R].
  Eigen::SparseMatrix<double> assemble() const;
  Eigen::VectorXd right_hand_side(const Eigen::VectorXd& f) const;

  // Volume change sum_t V_t tr(eps_t(u)) (linear measure), for incompressibility checks.
  double volume_change(const Eigen::VectorXd& u) const;

private:
  struct Krylov;  // MINRES state kept for resumption (in the .cpp)
  class UBlock;   // a M + c K_mu as a LinearOperator, for the displacement preconditioner

  void grow();
  void compute_tet(std::uint32_t t);
  void compute_vertex(std::uint32_t v);
  void invalidate() { ++version_; }
  void full_mask(const std::vector<std::uint8_t>& free);
  void setup_preconditioner();
  void precondition(const Eigen::VectorXd& r, Eigen::VectorXd& z) const;
  void project(Eigen::VectorXd& v) const;
  MixedStats solve_direct(const Eigen::VectorXd& b, Eigen::VectorXd& x);
  MixedStats solve_minres(const Eigen::VectorXd& b, Eigen::VectorXd& x);
  double preconditioned_norm(const Eigen::VectorXd& r) const;
  double relative_residual(const Eigen::VectorXd& b, const Eigen::VectorXd& x) const;
  void pressure_preconditioner();

  const TetMesh* mesh_;
  MixedMaterials materials_;
  FemKind kind_;
  MixedOptions opt_;
  FemModel model_;

  // Per tet (by TetId): V/4 R grad N_j in column j, 1/lambda, trace(R) - 3 (0 for Linear).
  std::vector<Eigen::Matrix<double, 3, 4>> rg_;
  std::vector<double> invlam_, rtrace_;
  // Per vertex slot: the pressure preconditioner's diagonal (0: no tets).
  Eigen::VectorXd pdiag_;
  Eigen::VectorXd p_;  // the last pressure
  double a_ = 0, c_ = 1;  // the system's mass and stiffness coefficients
  Eigen::VectorXd pinv_;  // per vertex slot: the pressure preconditioner's inverse (0: kept)

  // Solve state.
  std::uint64_t version_ = 1;          // bumped by anything that changes the operator
  std::vector<std::uint8_t> mask_;     // 4n: free displacements, then pressures with tets
  std::vector<std::uint8_t> umask_;    // 3n: for the displacement preconditioner
  std::uint64_t pc_version_ = 0;       // operator version the preconditioner was set up for
  std::vector<std::uint8_t> pc_mask_;  // and its mask
  std::unique_ptr<AggregationAmg> amg_;
  std::unique_ptr<UBlock> ublock_;
  int last_iterations_ = 0;
  bool use_amg_ = false;               // of the last setup (else block-Jacobi)
  std::unique_ptr<AsyncCholesky> chol_;  // MixedPreconditioner::Cholesky
  bool use_chol_ = false;
  BlockJacobi jacobi_;
  std::unique_ptr<Krylov> krylov_;
  Eigen::VectorXd kept_, akept_;       // the kept values of the last fresh start, A times them
  std::uint64_t akept_version_ = 0;
  mutable Eigen::VectorXd tmp_u_, tmp_z_, scratch_;
  // Per tet: the pressure block's coefficients, (C_t p)_v = cdiag p_v + coff sum_corners p.
  std::vector<double> cdiag_, coff_;
  // The product's per-corner shares (slot 4 t + local: force on u, then the pressure row),
  // gathered per vertex through its corner slots (rebuilt with the vertex).
  mutable std::vector<Eigen::Vector4d> corner_;
  std::vector<std::vector<std::uint32_t>> corner_slots_;
};

}  // namespace incise
