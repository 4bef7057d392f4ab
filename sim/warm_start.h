#pragma once
// Warm start across frames: predicts the next static solution by extrapolating the last ones
// (a tool moving steadily is the common case). It proposes directions, the first difference
// d1 = u_1 - u_2 and the second difference d2 = u_1 - 2 u_2 + u_3 (so linear and quadratic
// extrapolation are both in their span); CG starts from u_1 + a1 d1 + a2 d2 with the weights
// that minimize the initial residual, so a bad prediction falls back to the last solution
// (weights 0) and never starts worse than it. The history follows topology changes like every
// other per-vertex field (new vertices interpolated).
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "mesh/topology_change.h"

namespace incise {

class WarmStartPredictor {
public:
  void clear() { count_ = 0; }
  // A frame's solution (converged or not: a poor direction is what the line search rejects).
  void record(const Eigen::VectorXd& u);
  // The directions (0 on kept unknowns): none before two frames, then d1, then d1 and d2.
  // Returns how many were written to d.
  int directions(const std::vector<std::uint8_t>& free, std::vector<Eigen::VectorXd>& d) const;
  // Follows an edit batch: O(size of the change) unless the vectors grow.
  void apply(const TopologyChange& change, std::size_t vertex_slots);

private:
  Eigen::VectorXd u_[3];  // u_1, u_2, u_3: the latest first
  int count_ = 0;
};

}  // namespace incise
