// The multigrid's coarse factor (sim/linalg/block_cholesky.h) against a dense LL^T of the same matrix:
// random sparse block graphs with blocks of 0 to 6 unknowns, both triangles or the lower one
// given, duplicates summed; indefinite and singular matrices refused.
#include <catch2/catch.hpp>

#include <random>

#include <Eigen/Cholesky>
#include <Eigen/Dense>

#include "sim/linalg/block_cholesky.h"

using namespace incise;

namespace {

using Block = BlockCholesky6::Block;
using Vec = BlockCholesky6::Vec;

struct Problem {
  BlockCholesky6::Rows rows;
  std::vector<int> dims;
  std::vector<Eigen::Index> offset;  // into the dense compact matrix
  Eigen::MatrixXd dense;
};

// A = G G^T + shift I in compact unknowns, G sparse along a random block graph (a ring plus
// random chords, so the ordering has fill to make); the blocks handed over in both triangles
// (`both`) or the lower only, some split into two summands.
Problem random_problem(std::mt19937& rng, int n, bool both, double shift) {
  Problem p;
  std::uniform_int_distribution<int> dim(0, 6), node(0, n - 1);
  std::uniform_real_distribution<double> u(-1, 1);
  p.dims.resize(std::size_t(n));
  for (int& d : p.dims) d = dim(rng) < 2 ? dim(rng) : 6;  // mostly full blocks
  p.offset.assign(std::size_t(n) + 1, 0);
  for (int i = 0; i < n; ++i) p.offset[std::size_t(i) + 1] = p.offset[std::size_t(i)] + p.dims[std::size_t(i)];
  const Eigen::Index size = p.offset.back();
  std::vector<std::pair<int, int>> edges;
  for (int i = 0; i < n; ++i) edges.emplace_back(i, (i + 1) % n);
  for (int e = 0; e < n; ++e) edges.emplace_back(node(rng), node(rng));
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(size, size);
  auto fill = [&](int i, int j) {
    for (Eigen::Index r = 0; r < p.dims[std::size_t(i)]; ++r)
      for (Eigen::Index c = 0; c < p.dims[std::size_t(j)]; ++c) g(p.offset[std::size_t(i)] + r, p.offset[std::size_t(j)] + c) = u(rng);
  };
  for (int i = 0; i < n; ++i) fill(i, i);
  for (auto [i, j] : edges) fill(i, j);
  p.dense = g * g.transpose() + shift * Eigen::MatrixXd::Identity(size, size);
  p.rows.assign(std::size_t(n), {});
  std::uniform_real_distribution<double> half(0.2, 0.8);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      if (!both && j > i) continue;
      const int di = p.dims[std::size_t(i)], dj = p.dims[std::size_t(j)];
      if (di == 0 || dj == 0) continue;
      const auto sub = p.dense.block(p.offset[std::size_t(i)], p.offset[std::size_t(j)], di, dj);
      if (sub.cwiseAbs().maxCoeff() == 0 && i != j) continue;
      Block b = Block::Zero();
      b.topLeftCorner(di, dj) = sub;
      if (i == j) b.topRightCorner(6, 6).triangularView<Eigen::StrictlyUpper>().setConstant(1e30);  // never read
      const double s = half(rng);
      p.rows[std::size_t(i)].emplace_back(j, s * b);  // duplicates are summed
      if (i == j) b.triangularView<Eigen::StrictlyUpper>().setZero();
      p.rows[std::size_t(i)].emplace_back(j, (1 - s) * b);
    }
  return p;
}

}  // namespace

TEST_CASE("block Cholesky: the solve equals a dense LL^T on random block graphs", "[fem][amg]") {
  std::mt19937 rng(42);
  for (int trial = 0; trial < 30; ++trial) {
    const int n = 1 + trial * 7;
    const bool both = trial % 2 == 0;
    Problem p = random_problem(rng, n, both, 1e-3);
    INFO("trial " << trial << ", " << n << " blocks, both triangles " << both);
    BlockCholesky6 f;
    if (p.offset.back() == 0) {
      CHECK_FALSE(f.compute(p.rows, p.dims));  // nothing to factor
      continue;
    }
    REQUIRE(f.compute(p.rows, p.dims));
    std::uniform_real_distribution<double> u(-1, 1);
    std::vector<Vec> x(std::size_t(n), Vec::Zero());
    Eigen::VectorXd b(p.offset.back());
    for (int i = 0; i < n; ++i)
      for (int r = 0; r < 6; ++r) {
        if (r < p.dims[std::size_t(i)]) b[p.offset[std::size_t(i)] + r] = x[std::size_t(i)][r] = u(rng);
        else x[std::size_t(i)][r] = 0;
      }
    f.solve_in_place(x);
    const Eigen::VectorXd ref = p.dense.llt().solve(b);
    double err = 0;
    for (int i = 0; i < n; ++i)
      for (int r = 0; r < 6; ++r) {
        if (r < p.dims[std::size_t(i)]) err = std::max(err, std::abs(x[std::size_t(i)][r] - ref[p.offset[std::size_t(i)] + r]));
        else CHECK(x[std::size_t(i)][r] == 0);
      }
    CHECK(err <= 1e-9 * ref.cwiseAbs().maxCoeff());
    // L's entries: at least A's lower triangle, at most the dense one.
    const auto size = std::size_t(p.offset.back());
    CHECK(f.nonzeros() <= size * (size + 1) / 2);
    CHECK(f.nonzeros() >= size);
  }
}

TEST_CASE("block Cholesky: indefinite and singular matrices are refused", "[fem][amg]") {
  std::mt19937 rng(7);
  Problem p = random_problem(rng, 40, true, 1e-3);
  BlockCholesky6 f;
  REQUIRE(f.compute(p.rows, p.dims));
  // Indefinite: one diagonal entry far negative.
  Problem q = p;
  for (std::size_t i = 0; i < q.rows.size(); ++i)
    if (q.dims[i] > 0) {
      for (auto& [j, b] : q.rows[i])
        if (std::size_t(j) == i) b(0, 0) -= 1e3;
      break;
    }
  CHECK_FALSE(f.compute(q.rows, q.dims));
  CHECK_FALSE(f.ok());
  // Singular: G G^T with G of rank one less than the size (shift 0, one column of G zeroed
  // is not enough, so two nodes that are exact copies).
  BlockCholesky6::Rows rows(2);
  Block a = Block::Identity();
  rows[0].emplace_back(0, a);
  rows[1].emplace_back(1, a);
  rows[1].emplace_back(0, a);
  rows[0].emplace_back(1, a);
  CHECK_FALSE(f.compute(rows, {6, 6}));
  // The same with the off-diagonal block scaled by 0.5 is SPD.
  rows[1][1].second *= 0.5;
  rows[0][1].second *= 0.5;
  CHECK(f.compute(rows, {6, 6}));
}

TEST_CASE("block Cholesky: the factor does not depend on the order of the rows' entries", "[fem][amg]") {
  std::mt19937 rng(3);
  Problem p = random_problem(rng, 60, true, 1e-2);
  Problem q = p;
  for (auto& row : q.rows) std::reverse(row.begin(), row.end());
  BlockCholesky6 f, g;
  REQUIRE(f.compute(p.rows, p.dims));
  REQUIRE(g.compute(q.rows, q.dims));
  std::vector<Vec> x(p.rows.size(), Vec::Ones()), y = x;
  for (std::size_t i = 0; i < x.size(); ++i)
    for (int r = p.dims[i]; r < 6; ++r) x[i][r] = y[i][r] = 0;
  f.solve_in_place(x);
  g.solve_in_place(y);
  double diff = 0, scale = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    diff = std::max(diff, (x[i] - y[i]).cwiseAbs().maxCoeff());
    scale = std::max(scale, x[i].cwiseAbs().maxCoeff());
  }
  CHECK(diff <= 1e-12 * scale);
  CHECK(f.nonzeros() == g.nonzeros());
}

TEST_CASE("block Cholesky: a 3D grid of aggregates, its cliques in dense panels", "[fem][amg]") {
  // A 7x7x7 grid of nodes coupled to their 26 neighbours, as aggregates are: minimum degree
  // ends in cliques, which become supernodes (fewer than the nodes), and the solve still
  // matches a dense LL^T.
  const int g = 7, n = g * g * g;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1, 1);
  auto id = [&](int x, int y, int z) { return (z * g + y) * g + x; };
  BlockCholesky6::Rows rows(static_cast<std::size_t>(n));
  std::vector<int> dims(std::size_t(n), 6);
  dims[5] = 3;  // one aggregate that dropped its rotations
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(6 * n, 6 * n);
  for (int z = 0; z < g; ++z)
    for (int y = 0; y < g; ++y)
      for (int x = 0; x < g; ++x)
        for (int dz = -1; dz <= 1; ++dz)
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int X = x + dx, Y = y + dy, Z = z + dz;
              if (X < 0 || Y < 0 || Z < 0 || X >= g || Y >= g || Z >= g) continue;
              const int i = id(x, y, z), j = id(X, Y, Z);
              if (j >= i) continue;
              Block b = Block::Zero();
              b.topLeftCorner(dims[std::size_t(i)], dims[std::size_t(j)]).setRandom();
              b *= 0.1;
              rows[std::size_t(i)].emplace_back(j, b);
              dense.block(6 * i, 6 * j, 6, 6) = b;
              dense.block(6 * j, 6 * i, 6, 6) = b.transpose();
            }
  for (int i = 0; i < n; ++i) {  // diagonally dominant: SPD
    Block d = Block::Zero();
    const int di = dims[std::size_t(i)];
    d.topLeftCorner(di, di).setIdentity();
    d *= 30;
    rows[std::size_t(i)].emplace_back(i, d);
    dense.block(6 * i, 6 * i, 6, 6) = d;
    for (int p = di; p < 6; ++p) dense(6 * i + p, 6 * i + p) = 1;
  }
  BlockCholesky6 f;
  REQUIRE(f.compute(rows, dims));
  CHECK(f.supernodes() < std::size_t(n) * 2 / 3);
  std::vector<Vec> x(static_cast<std::size_t>(n));
  Eigen::VectorXd b = Eigen::VectorXd::Zero(6 * n);
  for (int i = 0; i < n; ++i)
    for (int p = 0; p < dims[std::size_t(i)]; ++p) b[6 * i + p] = x[std::size_t(i)][p] = u(rng);
  for (int i = 0; i < n; ++i)
    for (int p = dims[std::size_t(i)]; p < 6; ++p) x[std::size_t(i)][p] = 0;
  f.solve_in_place(x);
  const Eigen::VectorXd ref = dense.llt().solve(b);
  double err = 0;
  for (int i = 0; i < n; ++i)
    for (int p = 0; p < 6; ++p) err = std::max(err, std::abs(x[std::size_t(i)][p] - ref[6 * i + p]));
  CHECK(err <= 1e-10 * ref.cwiseAbs().maxCoeff());
}
