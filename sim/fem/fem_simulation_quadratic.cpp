// FemSimulation's frames on 10-node tets (Formulation::Quadratic, MixedQuadratic): the same
// constraints, loads and integrators as the linear path, assembled and solved by the
// QuadraticSolver (sim/fem/quadratic_solver.h). Not the real-time path: no budget, no warm-start
// prediction, and a topology change rebuilds the P2 view (O(mesh)).
#include <chrono>

#include "mesh/clock.h"
#include "mesh/errors.h"
#include "sim/fem/fem_simulation.h"
#include "sim/fem/quadratic_solver.h"

namespace incise {

void FemSimulation::make_quadratic() {
  if (opt_.cg.budget_ms > 0)
    throw InvalidArgument("fem: quadratic tets are solved to tolerance; a frame budget (budget_ms) cannot be honoured");
  if (opt_.inversion_barrier.j_min > 0) throw InvalidArgument("fem: quadratic tets have no inversion barrier");
  QuadraticOptions qo;
  qo.taylor_hood = opt_.formulation == Formulation::MixedQuadratic;
  qo.direct = opt_.method == SolverMethod::Direct;
  qo.preconditioner = opt_.cg.preconditioner;
  qo.tolerance = opt_.cg.tolerance;
  qo.max_iterations = opt_.cg.max_iterations;
  quadratic_ = std::make_unique<QuadraticSolver>(*mesh_, MixedMaterials(materials_), opt_.kind, qo);
  // Mid-edge nodes start on the straight edge between their corners (a change's new nodes too).
  const P2Mesh& p2 = quadratic_->p2();
  qu_ = p2_from_corners(p2, u_);
  qv_ = p2_from_corners(p2, v_);
  qf_ = Eigen::VectorXd::Zero(Eigen::Index(quadratic_->num_dofs()));
}

void FemSimulation::add_face_traction(VertexId a, VertexId b, VertexId c, const Vec3& t) {
  if (quadratic_) {
    quadratic_->add_face_traction(a, b, c, t, qf_);
    return;
  }
  const Vec3 pa = mesh_->rest(a), pb = mesh_->rest(b), pc = mesh_->rest(c);
  const double area = 0.5 * (pb - pa).cross(pc - pa).norm();
  for (VertexId v : {a, b, c}) add_force(v, t * area / 3);
}

void FemSimulation::step_quadratic() {
  QuadraticSolver& qs = *quadratic_;
  const P2Mesh& p2 = qs.p2();
  const auto nc = Eigen::Index(3 * p2.corner_slots), dofs = Eigen::Index(qs.num_dofs());
  // Constraints: a corner's own; a mid-edge node holds the axes both its ends hold, at the mean
  // of their targets (a prescribed linear field is reproduced exactly).
  std::vector<std::uint8_t> free(std::size_t(dofs), 1);
  Eigen::VectorXd target = Eigen::VectorXd::Zero(dofs);
  for (Eigen::Index i = 0; i < nc; ++i) {
    free[std::size_t(i)] = i < Eigen::Index(free_.size()) ? free_[std::size_t(i)] : 0;
    target[i] = i < target_.size() ? target_[i] : 0.0;
  }
  for (std::size_t e = 0; e < p2.edges.size(); ++e) {
    const auto& ab = p2.edges[e];
    const unsigned held = constrained_[ab[0]] & constrained_[ab[1]];
    const Eigen::Index n = 3 * Eigen::Index(p2.corner_slots + e);
    for (int k = 0; k < 3; ++k)
      if (held >> k & 1u) {
        free[std::size_t(n + k)] = 0;
        target[n + k] = 0.5 * (target_[3 * Eigen::Index(ab[0]) + k] + target_[3 * Eigen::Index(ab[1]) + k]);
      }
  }
  Eigen::VectorXd f = qf_;
  f.head(nc) += f_ext_.head(nc);
  if (opt_.gravity.squaredNorm() > 0) f += qs.body_force(opt_.gravity);
  auto record = [&](const QuadraticStats& q) {
    stats_.iterations += q.iterations;
    stats_.products += q.iterations;
    stats_.relative_residual = q.relative_residual;
    stats_.solve_ms += q.solve_ms;
    if (!q.converged) {
      stats_.info = q.iterations > 0 && q.message.find("not converged") != std::string::npos ? SolveInfo::NoConvergence
                                                                                               : SolveInfo::NumericalIssue;
      stats_.message = q.message;
    }
  };
  const bool corot = opt_.kind == FemKind::Corotational;
  Eigen::VectorXd x(dofs);
  auto guess = [&](const Eigen::VectorXd& start) {
    x = opt_.warm_start ? start : Eigen::VectorXd::Zero(dofs);
    for (Eigen::Index i = 0; i < dofs; ++i)
      if (!free[std::size_t(i)]) x[i] = target[i];
  };
  if (!opt_.dynamic) {
    const int rounds = corot ? opt_.nonlinear_iterations : 1;
    for (int it = 0; it < rounds; ++it) {
      qs.update_rotations(qu_);
      guess(qu_);
      record(qs.solve(0, 1, f, free, x));
      if (stats_.info == SolveInfo::NumericalIssue) break;
      qu_ = x;
    }
  } else {
    // Backward Euler for the new displacement u' (QuadraticSolver's system): a = 1 + dt damping,
    // c = dt^2, b = dt^2 f + a M u + dt M v; then v' = (u' - u) / dt.
    const double dt = opt_.dt, a = 1 + dt * opt_.damping;
    qs.update_rotations(qu_);
    const Eigen::VectorXd b = dt * dt * f + qs.mass() * (a * qu_ + dt * qv_);
    guess(Eigen::VectorXd(qu_ + dt * qv_));
    record(qs.solve(a, dt * dt, b, free, x));
    if (stats_.info != SolveInfo::NumericalIssue) {
      qv_ = (x - qu_) / dt;
      qu_ = x;
    }
  }
  u_.head(nc) = qu_.head(nc);
  v_.head(nc) = qv_.head(nc);
  check_finite(u_, stats_);
}

}  // namespace incise
