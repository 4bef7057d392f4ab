#include "quality/conditioning.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "mesh/errors.h"

namespace incise {

SolverEstimate estimate_solver(const TetMesh& mesh, const SolverEstimateOptions& opt, std::span<const Vec3> positions) {
  if (!(opt.poisson_ratio > -1.0 && opt.poisson_ratio < 0.5))
    throw InvalidArgument("estimate_solver: Poisson ratio must be in (-1, 0.5)");
  if (!(opt.tolerance > 0 && opt.tolerance < 1)) throw InvalidArgument("estimate_solver: tolerance must be in (0, 1)");
  SolverEstimate est;
  est.tolerance = opt.tolerance;
  est.poisson_ratio = opt.poisson_ratio;
  est.elasticity_factor = 2.0 * (1.0 - opt.poisson_ratio) / (1.0 - 2.0 * opt.poisson_ratio);
  if (mesh.num_tets() == 0) {
    est.reason = "no tets";
    return est;
  }
  auto pos = [&](VertexId v) -> const Vec3& { return positions.empty() ? mesh.rest(v) : positions[v.idx()]; };

  std::vector<double> row(mesh.vertex_capacity(), 0.0);  // sum of element lambda_max bounds
  std::vector<std::uint8_t> used(mesh.vertex_capacity(), 0);
  double total_volume = 0;
  std::size_t degenerate = 0;
  for (TetId t : mesh.tets()) {
    const auto& v = mesh.tet_vertices(t);
    const Vec3& p0 = pos(v[0]);
    Vec3 e1 = pos(v[1]) - p0, e2 = pos(v[2]) - p0, e3 = pos(v[3]) - p0, e4 = pos(v[2]) - pos(v[1]),
         e5 = pos(v[3]) - pos(v[1]);
    double l2max = std::max({e1.squaredNorm(), e2.squaredNorm(), e3.squaredNorm(), e4.squaredNorm(),
                             e5.squaredNorm(), (pos(v[3]) - pos(v[2])).squaredNorm()});
    double vol = std::abs(e1.dot(e2.cross(e3))) / 6.0;
    total_volume += vol;
    for (VertexId x : v) used[x.idx()] = 1;
    if (!(vol > opt.degenerate_volume * l2max * std::sqrt(l2max))) {
      ++degenerate;
      continue;
    }
    // Face area vectors are twice the areas: sum A^2 = sum |n|^2 / 4.
    double a2 = 0.25 * (e4.cross(e5).squaredNorm() + e3.cross(e2).squaredNorm() + e1.cross(e3).squaredNorm() +
                        e2.cross(e1).squaredNorm());
    double lam = a2 / (9.0 * vol);
    for (VertexId x : v) row[x.idx()] += lam;
  }
  if (degenerate > 0) {
    est.reason = std::to_string(degenerate) + " degenerate tet(s) make the stiffness matrix singular";
    return est;
  }

  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  std::size_t n = 0;
  for (std::uint32_t i = 0; i < row.size(); ++i) {
    if (!used[i]) continue;
    ++n;
    lo = lo.cwiseMin(pos(VertexId(i)));
    hi = hi.cwiseMax(pos(VertexId(i)));
    if (row[i] > est.lambda_max_bound) {
      est.lambda_max_bound = row[i];
      est.lambda_max_vertex = VertexId(i);
    }
  }
  constexpr double kPi = 3.14159265358979323846;
  est.domain_size = (hi - lo).maxCoeff();
  const double lambda1 = std::pow(kPi / (2.0 * est.domain_size), 2);
  est.lambda_min_estimate = lambda1 * total_volume / static_cast<double>(n);
  est.kappa_laplace = est.lambda_max_bound / est.lambda_min_estimate;
  est.kappa = est.kappa_laplace * est.elasticity_factor;
  est.cg_iterations = 0.5 * std::sqrt(est.kappa) * std::log(2.0 / opt.tolerance);
  est.available = std::isfinite(est.kappa) && est.kappa > 0;
  if (!est.available) est.reason = "condition number overflows";
  return est;
}

}  // namespace incise
