#include "cut/tet_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace incise {

void TetGrid::rest_box(const TetMesh& mesh, TetId t, Vec3& lo, Vec3& hi) const {
  lo = hi = mesh.rest(mesh.tet_vertices(t)[0]);
  for (VertexId v : mesh.tet_vertices(t)) {
    lo = lo.cwiseMin(mesh.rest(v));
    hi = hi.cwiseMax(mesh.rest(v));
  }
}

std::array<std::int64_t, 3> TetGrid::cell_of(const Vec3& x) const {
  std::array<std::int64_t, 3> c{};
  for (int a = 0; a < 3; ++a) {
    const double f = std::floor((x[a] - origin_[a]) / cell_);
    // Clamped: points outside the grid's box (a far query, a vertex an edit put outside the
    // first box) land in the border cells, which stay correct, only fuller.
    c[std::size_t(a)] = std::int64_t(std::clamp(f, 0.0, double(dims_[std::size_t(a)] - 1)));
  }
  return c;
}

void TetGrid::build(const TetMesh& mesh) {
  cells_.clear();
  const std::vector<TetId> tets = mesh.tets();
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::max()), hi = -lo;
  double extent = 0;
  for (TetId t : tets) {
    Vec3 a, b;
    rest_box(mesh, t, a, b);
    lo = lo.cwiseMin(a);
    hi = hi.cwiseMax(b);
    extent += (b - a).maxCoeff();
  }
  if (tets.empty()) lo = hi = Vec3::Zero();
  const Vec3 size = (hi - lo).cwiseMax(0.0);
  // Cells about twice the mean tet extent (a tet overlaps a few cells, a cell lists a few
  // dozen tets), but never more cells than tets.
  double cell = tets.empty() ? 1.0 : 2.0 * extent / double(tets.size());
  const double volume = std::max(size.prod(), 0.0);
  const double max_cells = std::max<double>(64.0, double(tets.size()));
  if (!(cell > 0)) cell = std::max(size.maxCoeff(), 1.0);
  if (volume / (cell * cell * cell) > max_cells) cell = std::cbrt(volume / max_cells);
  cell_ = cell;
  origin_ = lo;
  for (int a = 0; a < 3; ++a)
    dims_[std::size_t(a)] = std::clamp<std::int64_t>(std::int64_t(std::ceil(size[a] / cell_)), 1, 1 << 20);
  while (double(dims_[0]) * double(dims_[1]) * double(dims_[2]) > 4.0 * max_cells) {  // flat boxes
    cell_ *= 1.25;
    for (int a = 0; a < 3; ++a)
      dims_[std::size_t(a)] = std::max<std::int64_t>(1, std::int64_t(std::ceil(size[a] / cell_)));
  }
  cells_.assign(std::size_t(dims_[0] * dims_[1] * dims_[2]), {});
  range_.assign(mesh.tet_capacity(), {});
  box_.assign(mesh.tet_capacity(), {});
  for (TetId t : tets) insert(mesh, t);
  const std::size_t room = mesh.tet_capacity() + mesh.tet_capacity() / 8 + 1024;
  in_cell_.assign(room, 0);
  in_query_.assign(room, 0);
  cell_stamp_ = query_stamp_ = 0;
}

void TetGrid::insert(const TetMesh& mesh, TetId t) {
  Vec3 a, b;
  rest_box(mesh, t, a, b);
  const auto c0 = cell_of(a), c1 = cell_of(b);
  if (range_.size() <= t.idx()) {
    range_.resize(std::max<std::size_t>(t.idx() + 1, range_.size() + range_.size() / 2));
    box_.resize(range_.size());
  }
  box_[t.idx()] = {a[0], a[1], a[2], b[0], b[1], b[2]};
  range_[t.idx()] = {std::int32_t(c0[0]), std::int32_t(c0[1]), std::int32_t(c0[2]),
                     std::int32_t(c1[0]), std::int32_t(c1[1]), std::int32_t(c1[2])};
  for (std::int64_t k = c0[2]; k <= c1[2]; ++k)
    for (std::int64_t j = c0[1]; j <= c1[1]; ++j)
      for (std::int64_t i = c0[0]; i <= c1[0]; ++i) cells_[index(i, j, k)].push_back(t.idx());
}

void TetGrid::update(const TetMesh& mesh, const TopologyChange& change) {
  if (!built()) return;
  // Removed tets stay listed until a query visits their cells (then they are dead, or alive
  // under a reused id and checked against the cell again): removal costs nothing here.
  for (TetId t : change.added_tets)
    if (mesh.is_alive(t)) insert(mesh, t);
}

std::vector<TetId> TetGrid::query(const TetMesh& mesh, const Vec3& lo, const Vec3& hi, double grow) {
  std::vector<TetId> out;
  if (!built()) return out;
  const Vec3 qlo = lo.array() - grow, qhi = hi.array() + grow;
  if (in_cell_.size() < mesh.tet_capacity()) {  // geometric: amortized over the growth
    const std::size_t room = std::max(mesh.tet_capacity(), in_cell_.size() + in_cell_.size() / 2);
    in_cell_.resize(room, 0);
    in_query_.resize(room, 0);
  }
  if (++query_stamp_ == 0) {  // wrapped: forget old stamps
    std::fill(in_query_.begin(), in_query_.end(), 0);
    query_stamp_ = 1;
  }
  const auto c0 = cell_of(qlo), c1 = cell_of(qhi);
  for (std::int64_t k = c0[2]; k <= c1[2]; ++k)
    for (std::int64_t j = c0[1]; j <= c1[1]; ++j)
      for (std::int64_t i = c0[0]; i <= c1[0]; ++i) {
        auto& list = cells_[index(i, j, k)];
        if (++cell_stamp_ == 0) {
          std::fill(in_cell_.begin(), in_cell_.end(), 0);
          cell_stamp_ = 1;
        }
        // Clean the cell while reading it: drop dead tets, repeats (a tet re-added under the
        // same id after a vertex move), and tets whose box left this cell (re-inserted since
        // with another box, or a new tet under a removed one's id).
        std::size_t keep = 0;
        for (std::uint32_t id : list) {
          const TetId t(id);
          if (!mesh.is_alive(t) || in_cell_[id] == cell_stamp_) continue;
          const auto& r = range_[id];
          if (i < r[0] || i > r[3] || j < r[1] || j > r[4] || k < r[2] || k > r[5]) continue;
          in_cell_[id] = cell_stamp_;
          list[keep++] = id;
          if (in_query_[id] == query_stamp_) continue;
          in_query_[id] = query_stamp_;
          const auto& x = box_[id];
          if (x[0] <= qhi[0] && x[1] <= qhi[1] && x[2] <= qhi[2] && x[3] >= qlo[0] && x[4] >= qlo[1] && x[5] >= qlo[2])
            out.push_back(t);
        }
        list.resize(keep);
      }
  return out;
}

}  // namespace incise
