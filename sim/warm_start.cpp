#include "sim/warm_start.h"

#include <algorithm>

#include "sim/fem_model.h"

namespace incise {

void WarmStartPredictor::record(const Eigen::VectorXd& u) {
  u_[2].swap(u_[1]);
  u_[1].swap(u_[0]);
  u_[0] = u;
  count_ = std::min(count_ + 1, 3);
}

int WarmStartPredictor::directions(const std::vector<std::uint8_t>& free, std::vector<Eigen::VectorXd>& d) const {
  const int k = std::min(count_ - 1, 2);
  if (k <= 0) return 0;
  const Eigen::Index n = u_[0].size();
  for (int i = 1; i <= k; ++i)
    if (u_[i].size() != n || std::size_t(n) > free.size()) return 0;
  d.resize(std::size_t(k));
  for (int j = 0; j < k; ++j) d[std::size_t(j)].setZero(Eigen::Index(free.size()));
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!free[std::size_t(i)]) continue;
    d[0][i] = u_[0][i] - u_[1][i];
    if (k == 2) d[1][i] = u_[0][i] - 2 * u_[1][i] + u_[2][i];
  }
  return k;
}

void WarmStartPredictor::apply(const TopologyChange& change, std::size_t vertex_slots) {
  for (int i = 0; i < count_; ++i) interpolate_added_vertices(change, vertex_slots, u_[i]);
}

}  // namespace incise
