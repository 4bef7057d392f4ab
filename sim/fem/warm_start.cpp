#include "sim/fem/warm_start.h"

#include <algorithm>

#include "sim/fem/fem_model.h"

namespace incise {

void WarmStartPredictor::record(const Eigen::VectorXd& u) {
  for (int i = kHistory - 1; i > 0; --i) u_[i].swap(u_[i - 1]);
  u_[0] = u;
  count_ = std::min(count_ + 1, kHistory);
}

int WarmStartPredictor::directions(const std::vector<std::uint8_t>& free, std::vector<Eigen::VectorXd>& d) const {
  const int k = count_ - 1;
  if (k <= 0) return 0;
  const Eigen::Index n = u_[0].size();
  for (int i = 1; i <= k; ++i)
    if (u_[i].size() != n || std::size_t(n) > free.size()) return 0;
  d.resize(std::size_t(k));
  for (int j = 0; j < k; ++j) d[std::size_t(j)].setZero(Eigen::Index(free.size()));
  // Per unknown, the backward differences in place: after pass m, w[j] = nabla^m u_{j+1}.
  double w[kHistory];
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!free[std::size_t(i)]) continue;
    for (int j = 0; j <= k; ++j) w[j] = u_[j][i];
    for (int m = 1; m <= k; ++m) {
      for (int j = 0; j + m <= k; ++j) w[j] -= w[j + 1];
      d[std::size_t(m - 1)][i] = w[0];
    }
  }
  return k;
}

void WarmStartPredictor::apply(const TopologyChange& change, std::size_t vertex_slots) {
  for (int i = 0; i < count_; ++i) interpolate_added_vertices(change, vertex_slots, u_[i]);
}

}  // namespace incise
