#include "mesh/point_locator.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>

#include "mesh/rest_bounds.h"

namespace incise {

namespace {

// Barycentric coordinates of p in tet v (may be negative outside); false for a flat tet.
bool barycentric(const TetMesh& m, TetId t, const Vec3& p, std::array<double, 4>& w) {
  const auto v = m.tet_vertices(t);
  Eigen::Matrix3d e;
  e << m.rest(v[1]) - m.rest(v[0]), m.rest(v[2]) - m.rest(v[0]), m.rest(v[3]) - m.rest(v[0]);
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(e);
  if (!lu.isInvertible()) return false;
  const Vec3 x = lu.solve(p - m.rest(v[0]));
  w = {1 - x.sum(), x[0], x[1], x[2]};
  return true;
}

}  // namespace

// By the Voronoi regions of the triangle's corners and edges.
Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double den = 1 / (va + vb + vc);
  return a + ab * (vb * den) + ac * (vc * den);
}

double star_coordinates(const TetMesh& mesh, VertexId v, const Vec3& p, std::vector<VertexId>& parents,
                        std::vector<double>& weights) {
  double best = -std::numeric_limits<double>::infinity();
  for (TetId t : mesh.incident_tets(v)) {
    const auto& tv = mesh.tet_vertices(t);
    Eigen::Matrix3d a;
    for (int k = 0; k < 3; ++k) a.col(k) = mesh.rest(tv[std::size_t(k) + 1]) - mesh.rest(tv[0]);
    const Vec3 l = a.partialPivLu().solve(p - mesh.rest(tv[0]));
    const double w[4] = {1 - l.sum(), l[0], l[1], l[2]};
    const double m = std::min({w[0], w[1], w[2], w[3]});
    if (m > best) {
      best = m;
      parents.assign(tv.begin(), tv.end());
      weights.assign(w, w + 4);
    }
  }
  return best;
}

PointLocator::PointLocator(const TetMesh& mesh) : mesh_(&mesh) {
  if (mesh.num_tets() == 0) return;
  const RestBounds box = rest_bounds(mesh);
  const Vec3 lo = box.lo, hi = box.hi;
  // About one tet per cell: cells of the mean tet's size.
  const Vec3 ext = (hi - lo).cwiseMax(1e-12 * std::max(1.0, (hi - lo).maxCoeff()));
  cell_ = std::cbrt(ext.prod() / double(mesh.num_tets())) * 1.5;
  if (!(cell_ > 0)) cell_ = ext.maxCoeff();
  origin_ = lo;
  for (int d = 0; d < 3; ++d) dims_[std::size_t(d)] = std::max<std::int64_t>(1, std::int64_t(ext[d] / cell_) + 1);
  const std::size_t ncells = std::size_t(dims_[0] * dims_[1] * dims_[2]);
  auto boxes = [&](auto&& visit) {
    for (TetId t : mesh.tets()) {
      Vec3 a = mesh.rest(mesh.tet_vertices(t)[0]), b = a;
      for (VertexId v : mesh.tet_vertices(t)) {
        a = a.cwiseMin(mesh.rest(v));
        b = b.cwiseMax(mesh.rest(v));
      }
      const auto c0 = cell_of(a), c1 = cell_of(b);
      for (std::int64_t k = c0[2]; k <= c1[2]; ++k)
        for (std::int64_t j = c0[1]; j <= c1[1]; ++j)
          for (std::int64_t i = c0[0]; i <= c1[0]; ++i) visit(std::size_t((k * dims_[1] + j) * dims_[0] + i), t);
    }
  };
  start_.assign(ncells + 1, 0);
  boxes([&](std::size_t c, TetId) { ++start_[c + 1]; });
  for (std::size_t c = 0; c < ncells; ++c) start_[c + 1] += start_[c];
  tets_.resize(start_[ncells]);
  std::vector<std::uint32_t> fill(start_.begin(), start_.end() - 1);
  boxes([&](std::size_t c, TetId t) { tets_[fill[c]++] = t.idx(); });
}

std::array<std::int64_t, 3> PointLocator::cell_of(const Vec3& p) const {
  std::array<std::int64_t, 3> c;
  for (int d = 0; d < 3; ++d)
    c[std::size_t(d)] = std::clamp<std::int64_t>(std::int64_t(std::floor((p[d] - origin_[d]) / cell_)), 0, dims_[std::size_t(d)] - 1);
  return c;
}

void PointLocator::try_cell(std::int64_t i, std::int64_t j, std::int64_t k, const Vec3& p, PointLocation& best) const {
  if (i < 0 || j < 0 || k < 0 || i >= dims_[0] || j >= dims_[1] || k >= dims_[2]) return;
  const std::size_t c = std::size_t((k * dims_[1] + j) * dims_[0] + i);
  for (std::uint32_t s = start_[c]; s < start_[c + 1]; ++s) {
    const TetId t(tets_[s]);
    std::array<double, 4> w;
    if (!barycentric(*mesh_, t, p, w)) continue;
    if (*std::min_element(w.begin(), w.end()) >= -1e-12) {
      // Inside (to rounding): exact weights, clamped so that they stay a convex combination.
      double sum = 0;
      for (double& x : w) sum += (x = std::max(x, 0.0));
      for (double& x : w) x /= sum;
      best = {t, w, 0};
      return;
    }
    // Outside: the nearest point of the tet lies on one of its faces.
    const auto v = mesh_->tet_vertices(t);
    Vec3 q = Vec3::Zero();
    double d = std::numeric_limits<double>::max();
    for (const auto& f : kFaceLocal) {
      const Vec3 near = closest_on_triangle(p, mesh_->rest(v[std::size_t(f[0])]), mesh_->rest(v[std::size_t(f[1])]),
                                            mesh_->rest(v[std::size_t(f[2])]));
      if ((near - p).norm() < d) d = (near - p).norm(), q = near;
    }
    if (best.tet.is_valid() && d >= best.distance) continue;
    barycentric(*mesh_, t, q, w);
    double sum = 0;  // q is on the tet: only rounding makes a weight negative
    for (double& x : w) sum += (x = std::max(x, 0.0));
    for (double& x : w) x /= sum;
    if (!best.tet.is_valid() || d < best.distance) best = {t, w, d};
  }
}

PointLocation PointLocator::locate(const Vec3& p) const {
  PointLocation best{TetId(), {0, 0, 0, 0}, std::numeric_limits<double>::max()};
  if (start_.empty()) return best;
  const auto c = cell_of(p);
  // Rings of cells around p's (clamped) cell, until one holds p or the nearest found is closer
  // than anything further out can be.
  const std::int64_t max_ring = std::max({dims_[0], dims_[1], dims_[2]});
  for (std::int64_t r = 0; r <= max_ring; ++r) {
    for (std::int64_t k = c[2] - r; k <= c[2] + r; ++k)
      for (std::int64_t j = c[1] - r; j <= c[1] + r; ++j)
        for (std::int64_t i = c[0] - r; i <= c[0] + r; ++i) {
          if (std::max({std::abs(i - c[0]), std::abs(j - c[1]), std::abs(k - c[2])}) != r) continue;  // the ring only
          try_cell(i, j, k, p, best);
          if (best.tet.is_valid() && best.distance == 0) return best;
        }
    // Cells beyond ring r are at least r cells from p's cell along some axis.
    if (best.tet.is_valid() && double(r) * cell_ >= best.distance) break;
  }
  return best;
}

void PointLocator::interpolate(const TetMesh& mesh, const PointLocation& at, const double* field, int width, double* out) {
  const auto v = mesh.tet_vertices(at.tet);
  for (int c = 0; c < width; ++c) {
    double s = 0;
    for (int l = 0; l < 4; ++l) s += at.weights[std::size_t(l)] * field[std::size_t(v[std::size_t(l)].idx()) * std::size_t(width) + std::size_t(c)];
    out[c] = s;
  }
}

}  // namespace incise
