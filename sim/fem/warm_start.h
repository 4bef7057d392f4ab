#pragma once
// Warm start across frames: predicts the next static solution by extrapolating the last ones
// (a tool moving steadily is the common case). It proposes directions, the backward differences
// of the last kHistory solutions, d_m = nabla^m u_1 (d1 = u_1 - u_2, d2 = u_1 - 2 u_2 + u_3,
// ...; polynomial extrapolation of order m is u_1 + d1 + ... + d_m, so orders 1 to 4 are all
// in their span). CG starts from u_1 + sum a_m d_m with the weights of the Galerkin projection
// (least energy-norm error over the span, which is what CG itself minimizes), falling back to
// the weights of least residual when the Galerkin start has a larger residual than u_1; either
// way it never starts with a larger residual than the last solution (weights 0).
// Why four: the history is noisy (each frame converged only to the tolerance) and a
// corotational path is not polynomial; the projection picks the order that pays, and with an
// accurate solver (Cholesky) the higher orders do (bench_fem_precond, docs/solver.md).
// Each direction costs CG one operator product at the start of a frame.
// The history follows topology changes like every other per-vertex field (new vertices
// interpolated).
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "mesh/topology_change.h"

namespace incise {

class WarmStartPredictor {
public:
  static constexpr int kHistory = 5;  // solutions kept: up to kHistory - 1 directions

  void clear() { count_ = 0; }
  // A frame's solution (converged or not: a poor direction is what the projection rejects).
  void record(const Eigen::VectorXd& u);
  // The directions (0 on kept unknowns): none before two frames, then d1, then d1 and d2, ...
  // Returns how many were written to d.
  int directions(const std::vector<std::uint8_t>& free, std::vector<Eigen::VectorXd>& d) const;
  // Follows an edit batch: O(size of the change) unless the vectors grow.
  void apply(const TopologyChange& change, std::size_t vertex_slots);

private:
  Eigen::VectorXd u_[kHistory];  // u_1, u_2, ...: the latest first
  int count_ = 0;
};

}  // namespace incise
