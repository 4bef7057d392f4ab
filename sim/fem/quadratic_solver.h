#pragma once
// QuadraticSolver: linear and corotational elasticity on 10-node tets (P2, sim/fem/p2_mesh.h), and
// Taylor-Hood (P2 displacement, P1 vertex pressure), assembled and solved for a reference:
// docs/solver.md#quadratic-tets.
//
// Unknowns: displacement of P2 node n at 3n..3n+2 over 3 * p2().num_nodes() (corners first, as
// FemModel's vertex slots, then the mid-edge nodes); Taylor-Hood's pressure of vertex v at v over
// p2().corner_slots. The system solved for the new displacement u' is
//   (a M + c K) u' = b + c b_R                                        (displacement only)
//   [ a M + c A    D^T   ] [u']   [ b + c b_R ]
//   [ D         -C / c   ] [q ] = [ c_R       ],   q = c p            (Taylor-Hood)
// with M the consistent mass, K the P2 stiffness, A its deviatoric part (the element at
// lambda = 0), D_ij = int L_i div N_j, C = int L_i L_j / lambda (0 at Poisson's ratio 0.5).
// Static: a = 0, c = 1. Backward Euler with step dt and damping d: a = 1 + d dt, c = dt^2 and
// b = dt^2 f + a M u + dt M v (FemSimulation builds it). Corotational: per tet the rotation R of
// the polar decomposition of the corners' deformation gradient (the linear part of the P2 field),
// K_R = R K R^T per node block, b_R = R K (X - R^T X), c_R = D (X - R^T X).
// Solvers: a sparse direct one (the project's LDL^T / CHOLMOD for K, SparseLU for the
// indefinite Taylor-Hood system), or CG (Jacobi, block-Jacobi per node, or the factor of the
// assembled matrix as preconditioner) and preconditioned MINRES for Taylor-Hood (its displacement
// block preconditioned the same way, the pressure by the lumped P1 mass times (1/mu + 1/lambda)/c).
// The factor preconditioner is kept between solves (see factor()): the frames of a corotational
// run then cost an assembly and a few iterations each, not a factorization. The direct solver
// keeps its factor (and Taylor-Hood's LU) the same way for linear tets, whose matrix changes
// only with a, c and the constraints.
// Constraints per displacement unknown: `free` (1 solved for, 0 kept at the value x holds).
// The mesh must not change while the solver lives (FemSimulation rebuilds it after a change).
#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "mesh/tet_mesh.h"
#include "sim/fem/fem_model.h"
#include "sim/fem/mixed_solver.h"
#include "sim/fem/p2_element.h"
#include "sim/fem/p2_mesh.h"
#include "sim/linalg/preconditioner.h"

namespace incise {

struct QuadraticOptions {
  bool taylor_hood = false;   // P1 pressure unknowns (Formulation::MixedQuadratic)
  bool direct = true;         // sparse direct; else CG, or MINRES for Taylor-Hood
  // CG / MINRES: None, Jacobi, BlockJacobi, or Cholesky (the assembled displacement block's
  // factor). Amg has no P2 hierarchy here: it is refused (InvalidArgument).
  Preconditioner preconditioner = Preconditioner::BlockJacobi;
  double tolerance = 1e-10;   // relative residual of the iterative solvers
  int max_iterations = 20000;
};

struct QuadraticStats {
  int iterations = 0;              // CG / MINRES iterations (0: direct)
  double relative_residual = 0;    // the true residual of the assembled system, relative to the effective b
  double solve_ms = 0;
  bool converged = false;
  std::string message;             // empty on success
};

class QuadraticSolver {
public:
  // O(mesh). Throws InvalidArgument for a bad material (Poisson's ratio 0.5 only with Taylor-Hood)
  // or an unusable option, InvalidMesh for a degenerate tet.
  QuadraticSolver(const TetMesh& mesh, const MixedMaterials& materials, FemKind kind, const QuadraticOptions& options);
  ~QuadraticSolver();

  const P2Mesh& p2() const { return p2_; }
  FemKind kind() const { return kind_; }
  const QuadraticOptions& options() const { return opt_; }
  std::size_t num_dofs() const { return 3 * p2_.num_nodes(); }
  // The mid-edge node of edge (a, b); throws InvalidArgument when no live tet has that edge.
  std::size_t mid_node(VertexId a, VertexId b) const;

  // Consistent loads: rho int N g per unknown; a uniform traction t on the boundary triangle
  // (a, b, c) added into f (the 6-node triangle: area / 3 on each mid-edge node, nothing on corners).
  Eigen::VectorXd body_force(const Vec3& g) const;
  void add_face_traction(VertexId a, VertexId b, VertexId c, const Vec3& t, Eigen::VectorXd& f) const;
  const Eigen::SparseMatrix<double>& mass() const { return mass_; }  // consistent, num_dofs() square
  // The assembled K (K_R; Taylor-Hood: A_R, the deviatoric block), num_dofs() square.
  Eigen::SparseMatrix<double> stiffness() const;

  // Corotational: per-tet rotations from displacement u (num_dofs() entries). No-op for Linear.
  void update_rotations(const Eigen::VectorXd& u);
  // Solves the system above; x holds the kept values on input and the solution on output
  // (num_dofs() entries). Taylor-Hood: the pressure p = q / c is kept (pressure()).
  QuadraticStats solve(double a, double c, const Eigen::VectorXd& b, const std::vector<std::uint8_t>& free,
                       Eigen::VectorXd& x);
  const Eigen::VectorXd& pressure() const { return pressure_; }  // per vertex slot (Taylor-Hood)

  // Per TetId, at the tet's centroid (dead slots 0): von Mises stress, for displacement u.
  std::vector<double> von_mises(const Eigen::VectorXd& u) const;

private:
  struct CachedFactor;
  // The factor of the displacement block for Preconditioner::Cholesky, kept while the
  // constraints and coefficients stay; a solve with an earlier frame's factor (a corotational
  // frame's rotations move little) gets stale_limit() iterations, max(20, twice what the first
  // solve with it took), then a fresh factor.
  // `free`: the mask k is factored on; `key`: the constraints it stands for (the full mask).
  const CachedFactor& factor(const Eigen::SparseMatrix<double>& k, const std::vector<std::uint8_t>& free,
                             const std::vector<std::uint8_t>& key, double a, double c);
  bool reusable(const std::vector<std::uint8_t>& key, double a, double c) const;
  struct CachedLu;  // Taylor-Hood's LU for the direct solver, kept like factor_ (linear tets)
  int stale_limit() const;
  void assemble(double a, double c, Eigen::SparseMatrix<double>& k, Eigen::SparseMatrix<double>& d,
                Eigen::VectorXd& b_r, Eigen::VectorXd& c_r) const;
  Eigen::Matrix<double, 30, 1> rest_nodes(std::size_t t) const;

  const TetMesh* mesh_;
  P2Mesh p2_;
  FemKind kind_;
  QuadraticOptions opt_;
  std::unordered_map<std::uint64_t, std::uint32_t> mid_;  // (lower, upper) vertex ids -> mid-edge node
  std::vector<P2Tet> tets_;                                // per TetId
  std::vector<double> mu_, lambda_, inv_lambda_, rho_;     // per TetId
  std::vector<Eigen::Matrix3d> rot_;                       // per TetId (identity for Linear)
  Eigen::SparseMatrix<double> mass_;
  Eigen::VectorXd pressure_;
  std::unique_ptr<CachedFactor> factor_;
  std::unique_ptr<CachedLu> lu_;
};

}  // namespace incise
