#pragma once
// Warm start across frames: predicts the next static solution by linear extrapolation of the
// last two converged ones (a tool moving steadily is the common case). It proposes only a
// direction d = u_1 - u_2 on the free unknowns; CG starts from u_1 + alpha d with the alpha
// that minimizes the initial residual, so a bad prediction falls back to the last solution
// (alpha = 0) and never starts worse than it. The history follows topology changes like every
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
  // d = u_1 - u_2 on free unknowns (0 on kept); false (d untouched) with fewer than two frames.
  bool direction(const std::vector<std::uint8_t>& free, Eigen::VectorXd& d) const;
  // Follows an edit batch: O(size of the change) unless the vectors grow.
  void apply(const TopologyChange& change, std::size_t vertex_slots);

private:
  Eigen::VectorXd last_, before_;
  int count_ = 0;
};

}  // namespace incise
