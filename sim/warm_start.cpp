#include "sim/warm_start.h"

#include <algorithm>

#include "sim/fem_model.h"

namespace incise {

void WarmStartPredictor::record(const Eigen::VectorXd& u) {
  before_.swap(last_);
  last_ = u;
  count_ = std::min(count_ + 1, 2);
}

bool WarmStartPredictor::direction(const std::vector<std::uint8_t>& free, Eigen::VectorXd& d) const {
  if (count_ < 2 || last_.size() != before_.size() || std::size_t(last_.size()) > free.size()) return false;
  d.setZero(Eigen::Index(free.size()));
  for (Eigen::Index i = 0; i < last_.size(); ++i)
    if (free[std::size_t(i)]) d[i] = last_[i] - before_[i];
  return true;
}

void WarmStartPredictor::apply(const TopologyChange& change, std::size_t vertex_slots) {
  if (count_ == 0) return;
  interpolate_added_vertices(change, vertex_slots, last_);
  if (count_ == 2) interpolate_added_vertices(change, vertex_slots, before_);
}

}  // namespace incise
