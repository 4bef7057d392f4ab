#include "sim/fem/quadratic_solver.h"

#include <chrono>
#include <cmath>

#include <Eigen/SparseLU>

#include "mesh/clock.h"
#include "mesh/errors.h"
#include "sim/fem/assembled_stiffness.h"
#include "sim/linalg/cg_solver.h"
#include "sim/fem/p2_element.h"
#include "sim/fem/rotation_extraction.h"

namespace incise {

namespace {

using Triplets = std::vector<Eigen::Triplet<double>>;

std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  if (a > b) std::swap(a, b);
  return (std::uint64_t(a) << 32) | b;
}

// An assembled symmetric matrix as CG's operator, with its per-node 3x3 diagonal blocks.
class SparseOperator : public LinearOperator {
public:
  explicit SparseOperator(const Eigen::SparseMatrix<double>& a) : a_(a) {
    diag_ = a.diagonal();
    blocks_.assign(std::size_t(a.rows() / 3), Eigen::Matrix3d::Zero());
    for (Eigen::Index c = 0; c < a.outerSize(); ++c)
      for (Eigen::SparseMatrix<double>::InnerIterator it(a, c); it; ++it)
        if (it.row() / 3 == it.col() / 3) blocks_[std::size_t(it.row() / 3)](it.row() % 3, it.col() % 3) = it.value();
  }
  Eigen::Index rows() const override { return a_.rows(); }
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const override { y = a_ * x; }
  const Eigen::VectorXd& diagonal() const override { return diag_; }
  const std::vector<Eigen::Matrix3d>& diagonal_blocks() const override { return blocks_; }

private:
  const Eigen::SparseMatrix<double>& a_;
  Eigen::VectorXd diag_;
  std::vector<Eigen::Matrix3d> blocks_;
};

// A factor of the assembled matrix (or of one near it: an earlier frame's) as a preconditioner
// (Preconditioner::Cholesky): exact when it is current, so CG converges in an iteration or two.
class FactorPreconditioner : public CgPreconditioner {
public:
  explicit FactorPreconditioner(const DirectSolver& solver) : solver_(solver) {}
  void setup(const LinearOperator&, const std::vector<std::uint8_t>*) override {}
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const override {
    z = Eigen::VectorXd::Zero(r.size());  // kept unknowns: 0
    solver_.solve(r, z);
  }

private:
  const DirectSolver& solver_;
};

// Block-rotation of a 30-vector / 30x30 matrix by R per node.
Eigen::Matrix<double, 30, 1> rotate(const Eigen::Matrix3d& r, const Eigen::Matrix<double, 30, 1>& x) {
  Eigen::Matrix<double, 30, 1> y;
  for (int a = 0; a < 10; ++a) y.segment<3>(3 * a) = r * x.segment<3>(3 * a);
  return y;
}
P2Matrix rotate(const Eigen::Matrix3d& r, const P2Matrix& k) {
  P2Matrix out;
  for (int a = 0; a < 10; ++a)
    for (int b = 0; b < 10; ++b) out.block<3, 3>(3 * a, 3 * b) = r * k.block<3, 3>(3 * a, 3 * b) * r.transpose();
  return out;
}

}  // namespace

QuadraticSolver::QuadraticSolver(const TetMesh& mesh, const MixedMaterials& materials, FemKind kind,
                                 const QuadraticOptions& options)
    : mesh_(&mesh), p2_(make_p2_mesh(mesh)), kind_(kind), opt_(options) {
  if (opt_.preconditioner == Preconditioner::Amg)
    throw InvalidArgument("quadratic tets: the amg preconditioner has no P2 hierarchy; use \"cholesky\", "
                          "\"block-jacobi\", \"jacobi\" or \"none\"");
  if (!(opt_.tolerance > 0 && opt_.tolerance < 1)) throw InvalidArgument("quadratic tets: tolerance: expected (0, 1)");
  for (std::size_t e = 0; e < p2_.edges.size(); ++e)
    mid_.emplace(edge_key(p2_.edges[e][0], p2_.edges[e][1]), std::uint32_t(p2_.corner_slots + e));
  const std::size_t nt = mesh.tet_capacity();
  tets_.resize(nt);
  mu_.assign(nt, 0), lambda_.assign(nt, 0), inv_lambda_.assign(nt, 0), rho_.assign(nt, 0);
  rot_.assign(nt, Eigen::Matrix3d::Identity());
  Triplets mt;
  const auto& unit = p2_unit_mass();
  for (TetId t : mesh.tets()) {
    const auto& v = mesh.tet_vertices(t);
    tets_[t.idx()] = make_p2_tet({mesh.rest(v[0]), mesh.rest(v[1]), mesh.rest(v[2]), mesh.rest(v[3])});
    const Material& m = materials.get(mesh.label(t));
    if (!opt_.taylor_hood && !(m.poisson < 0.5))
      throw InvalidArgument("quadratic tets: Poisson's ratio 0.5 needs the Taylor-Hood formulation (\"mixed-quadratic\")");
    mu_[t.idx()] = m.mu();
    lambda_[t.idx()] = opt_.taylor_hood ? 0.0 : m.lambda();
    inv_lambda_[t.idx()] = inverse_lambda(m);
    rho_[t.idx()] = m.density;
    const double s = m.density * tets_[t.idx()].volume;
    const auto& n = p2_.tets[t.idx()];
    for (int a = 0; a < 10; ++a)
      for (int b = 0; b < 10; ++b)
        for (int k = 0; k < 3; ++k)
          mt.emplace_back(3 * int(n[std::size_t(a)]) + k, 3 * int(n[std::size_t(b)]) + k, s * unit(a, b));
  }
  const auto dofs = Eigen::Index(num_dofs());
  mass_.resize(dofs, dofs);
  mass_.setFromTriplets(mt.begin(), mt.end());
  pressure_ = Eigen::VectorXd::Zero(Eigen::Index(p2_.corner_slots));
}

struct QuadraticSolver::CachedFactor {
  DirectSolver solver{true};
  std::vector<std::uint8_t> free;
  double a = -1, c = -1;
  int fresh_iterations = -1;  // of the first solve with it (-1: none yet)
};

struct QuadraticSolver::CachedLu {
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
  std::vector<std::uint8_t> free;
  double a = -1, c = -1;
};

QuadraticSolver::~QuadraticSolver() = default;

bool QuadraticSolver::reusable(const std::vector<std::uint8_t>& key, double a, double c) const {
  return factor_ && factor_->fresh_iterations >= 0 && factor_->free == key && factor_->a == a && factor_->c == c;
}

int QuadraticSolver::stale_limit() const {
  return std::max(20, 2 * (factor_ ? factor_->fresh_iterations : 0));
}

const QuadraticSolver::CachedFactor& QuadraticSolver::factor(const Eigen::SparseMatrix<double>& k,
                                                             const std::vector<std::uint8_t>& free,
                                                             const std::vector<std::uint8_t>& key, double a, double c) {
  const bool stale = !factor_ || factor_->free != key || factor_->a != a || factor_->c != c;
  if (stale) {
    factor_ = std::make_unique<CachedFactor>();
    factor_->solver.compute(k, free);
    factor_->free = key;
    factor_->a = a;
    factor_->c = c;
  }
  return *factor_;
}

std::size_t QuadraticSolver::mid_node(VertexId a, VertexId b) const {
  const auto it = mid_.find(edge_key(a.idx(), b.idx()));
  if (it == mid_.end())
    throw InvalidArgument("quadratic tets: no tet has the edge (" + std::to_string(a.idx()) + ", " +
                          std::to_string(b.idx()) + ")");
  return it->second;
}

Eigen::VectorXd QuadraticSolver::body_force(const Vec3& g) const {
  Eigen::VectorXd f = Eigen::VectorXd::Zero(Eigen::Index(num_dofs()));
  for (TetId t : mesh_->tets()) {
    const double s = rho_[t.idx()] * tets_[t.idx()].volume;
    const auto& n = p2_.tets[t.idx()];
    for (int a = 0; a < 10; ++a) f.segment<3>(3 * Eigen::Index(n[std::size_t(a)])) += s * p2_load_weight(a) * g;
  }
  return f;
}

void QuadraticSolver::add_face_traction(VertexId a, VertexId b, VertexId c, const Vec3& t, Eigen::VectorXd& f) const {
  const Vec3 pa = mesh_->rest(a), pb = mesh_->rest(b), pc = mesh_->rest(c);
  const double area = 0.5 * (pb - pa).cross(pc - pa).norm();
  for (const auto& [u, w] : {std::pair{a, b}, std::pair{b, c}, std::pair{a, c}})
    f.segment<3>(3 * Eigen::Index(mid_node(u, w))) += kP2FaceMidWeight * area * t;
  for (VertexId v : {a, b, c}) f.segment<3>(3 * Eigen::Index(v.idx())) += kP2FaceCornerWeight * area * t;
}

Eigen::Matrix<double, 30, 1> QuadraticSolver::rest_nodes(std::size_t t) const {
  Eigen::Matrix<double, 30, 1> x;
  for (int a = 0; a < 10; ++a) x.segment<3>(3 * a) = p2_.rest(*mesh_, p2_.tets[t][std::size_t(a)]);
  return x;
}

void QuadraticSolver::update_rotations(const Eigen::VectorXd& u) {
  if (kind_ != FemKind::Corotational) return;
  for (TetId t : mesh_->tets()) {
    const auto& n = p2_.tets[t.idx()];
    Eigen::Matrix3d f = Eigen::Matrix3d::Identity();
    for (int i = 0; i < 4; ++i) f += u.segment<3>(3 * Eigen::Index(n[std::size_t(i)])) * tets_[t.idx()].grad_l.row(i);
    rot_[t.idx()] = polar_rotation(f);
  }
}

void QuadraticSolver::assemble(double a, double c, Eigen::SparseMatrix<double>& k, Eigen::SparseMatrix<double>& d,
                               Eigen::VectorXd& b_r, Eigen::VectorXd& c_r) const {
  const auto dofs = Eigen::Index(num_dofs()), np = Eigen::Index(p2_.corner_slots);
  Triplets kt, dt;
  kt.reserve(mesh_->num_tets() * 900);
  b_r = Eigen::VectorXd::Zero(dofs);
  c_r = Eigen::VectorXd::Zero(np);
  const bool corot = kind_ == FemKind::Corotational;
  for (TetId t : mesh_->tets()) {
    const std::size_t ti = t.idx();
    const auto& n = p2_.tets[ti];
    const Eigen::Matrix3d& r = rot_[ti];
    const P2Matrix ke = p2_stiffness(tets_[ti], mu_[ti], lambda_[ti]);
    const P2Matrix kr = corot ? rotate(r, ke) : ke;
    Eigen::Matrix<double, 30, 1> gap = Eigen::Matrix<double, 30, 1>::Zero();  // X - R^T X
    if (corot) {
      const Eigen::Matrix<double, 30, 1> x = rest_nodes(ti);
      gap = x - rotate(r.transpose(), x);
      const Eigen::Matrix<double, 30, 1> br = rotate(r, Eigen::Matrix<double, 30, 1>(ke * gap));
      for (int p = 0; p < 10; ++p) b_r.segment<3>(3 * Eigen::Index(n[std::size_t(p)])) += c * br.segment<3>(3 * p);
    }
    for (int p = 0; p < 30; ++p)
      for (int q = 0; q < 30; ++q)
        kt.emplace_back(3 * int(n[std::size_t(p / 3)]) + p % 3, 3 * int(n[std::size_t(q / 3)]) + q % 3, c * kr(p, q));
    if (opt_.taylor_hood) {
      const Eigen::Matrix<double, 4, 30> de = p2_divergence(tets_[ti]);
      Eigen::Matrix<double, 4, 30> dr = de;
      if (corot)
        for (int p = 0; p < 10; ++p) dr.middleCols<3>(3 * p) = de.middleCols<3>(3 * p) * r.transpose();
      const Eigen::Vector4d cr = de * gap;
      for (int i = 0; i < 4; ++i) {
        c_r[Eigen::Index(n[std::size_t(i)])] += cr[i];
        for (int q = 0; q < 30; ++q) dt.emplace_back(int(n[std::size_t(i)]), 3 * int(n[std::size_t(q / 3)]) + q % 3, dr(i, q));
      }
    }
  }
  k.resize(dofs, dofs);
  k.setFromTriplets(kt.begin(), kt.end());
  if (a != 0) k += a * mass_;
  if (opt_.taylor_hood) {
    d.resize(np, dofs);
    d.setFromTriplets(dt.begin(), dt.end());
  }
}

Eigen::SparseMatrix<double> QuadraticSolver::stiffness() const {
  Eigen::SparseMatrix<double> k, d;
  Eigen::VectorXd br, cr;
  assemble(0, 1, k, d, br, cr);
  return k;
}

namespace {

// Preconditioned MINRES (Paige & Saunders: Lanczos in the P^-1 inner product, QR of the
// tridiagonal matrix by Givens rotations) on a symmetric operator; `precondition` must be SPD.
// x: start in, solution out. Returns the iterations; `estimate` the final ||r||_{P^-1} / ||b||_{P^-1}.
template <class Apply, class Precondition>
int minres(const Apply& apply, const Precondition& precondition, const Eigen::VectorXd& b, Eigen::VectorXd& x,
           double tolerance, int max_iterations, double& estimate) {
  Eigen::VectorXd zb;
  precondition(b, zb);
  const double bnorm = std::sqrt(std::max(0.0, b.dot(zb)));
  int k = 0;
  // The recurrence's residual drifts from the true one over long runs (a stale preconditioner):
  // convergence is confirmed on the true residual, and the iteration restarts from x otherwise.
  for (int restart = 0; restart < 10 && k < max_iterations; ++restart) {
    Eigen::VectorXd r = b, z, az, v_old = Eigen::VectorXd::Zero(b.size()), w_old = v_old, w_older = v_old;
    apply(x, az);
    r -= az;
    precondition(r, z);
    const double beta1 = std::sqrt(std::max(0.0, r.dot(z)));
    estimate = bnorm > 0 ? beta1 / bnorm : 0;
    if (beta1 == 0 || estimate <= tolerance) return k;
    Eigen::VectorXd v = r / beta1;
    z /= beta1;
    double beta = 0, eta = beta1, c_old = 1, s_old = 0, c = 1, s = 0;
    for (; k < max_iterations; ++k) {
      apply(z, az);
      const double alpha = z.dot(az);
      Eigen::VectorXd v_new = az - alpha * v - beta * v_old, z_new;
      precondition(v_new, z_new);
      const double beta_new = std::sqrt(std::max(0.0, v_new.dot(z_new)));
      // The previous two rotations on column k of the tridiagonal matrix, then a new one.
      const double eps = s_old * beta, tmp = c_old * beta;
      const double delta = c * tmp + s * alpha, gamma_bar = -s * tmp + c * alpha;
      const double gamma = std::hypot(gamma_bar, beta_new);
      if (!(gamma > 0)) break;
      c_old = c, s_old = s;
      c = gamma_bar / gamma, s = beta_new / gamma;
      Eigen::VectorXd w = (z - delta * w_old - eps * w_older) / gamma;
      x += c * eta * w;
      eta = -s * eta;
      w_older = std::move(w_old);
      w_old = std::move(w);
      if (std::abs(eta) / bnorm <= tolerance || !(beta_new > 0)) {
        ++k;
        break;
      }
      v_old = std::move(v);
      v = v_new / beta_new;
      z = z_new / beta_new;
      beta = beta_new;
    }
  }
  Eigen::VectorXd r = b, z, az;
  apply(x, az);
  r -= az;
  precondition(r, z);
  estimate = bnorm > 0 ? std::sqrt(std::max(0.0, r.dot(z))) / bnorm : 0;
  return k;
}

}  // namespace

QuadraticStats QuadraticSolver::solve(double a, double c, const Eigen::VectorXd& b, const std::vector<std::uint8_t>& free,
                                      Eigen::VectorXd& x) {
  const auto t0 = std::chrono::steady_clock::now();
  QuadraticStats st;
  const auto dofs = Eigen::Index(num_dofs());
  if (b.size() != dofs || x.size() != dofs || free.size() != std::size_t(dofs))
    throw InvalidArgument("quadratic tets: solve: vectors must have num_dofs() entries");
  Eigen::SparseMatrix<double> k, d;
  Eigen::VectorXd b_r, c_r;
  assemble(a, c, k, d, b_r, c_r);
  const Eigen::VectorXd rhs = b + b_r;
  // Kept values moved to the right-hand side; `xk` holds only them.
  Eigen::VectorXd xk = x;
  for (Eigen::Index i = 0; i < dofs; ++i)
    if (free[std::size_t(i)]) xk[i] = 0;
  if (!opt_.taylor_hood) {
    if (opt_.direct && kind_ == FemKind::Linear) {
      // a M + c K does not change while a, c and the constraints stay: one factor serves
      // every step of a dynamic run (the same cache as the factor preconditioner's).
      factor(k, free, free, a, c).solver.solve(rhs, x);
    } else if (opt_.direct) {
      DirectSolver ds(true);
      ds.compute(k, free);
      ds.solve(rhs, x);
    } else {
      SparseOperator op(k);
      CgOptions co;
      co.tolerance = opt_.tolerance;
      co.max_iterations = opt_.max_iterations;
      co.preconditioner = opt_.preconditioner == Preconditioner::Cholesky ? Preconditioner::None : opt_.preconditioner;
      ConjugateGradient cg(co);
      std::unique_ptr<FactorPreconditioner> pc;
      // An earlier frame's factor gets stale_limit() iterations; past them it is refreshed and
      // the solve goes on from where it stopped.
      for (int attempt = 0; attempt < 2; ++attempt) {
        const bool reused = attempt == 0 && opt_.preconditioner == Preconditioner::Cholesky && reusable(free, a, c);
        if (opt_.preconditioner == Preconditioner::Cholesky) {
          if (!reused) factor_.reset();
          pc = std::make_unique<FactorPreconditioner>(factor(k, free, free, a, c).solver);
          cg.set_preconditioner(pc.get());
        }
        cg.set_max_iterations(reused ? stale_limit() : opt_.max_iterations);
        cg.compute(op, &free);
        cg.solve_with_guess(rhs, x);
        st.iterations += cg.iterations();
        if (opt_.preconditioner == Preconditioner::Cholesky && !reused) factor_->fresh_iterations = cg.iterations();
        if (cg.stats().converged() || !reused) break;
      }
      if (!cg.stats().converged()) st.message = "quadratic tets: cg: " + cg.stats().message;
    }
    Eigen::VectorXd res = rhs - k * x, beff = rhs - k * xk;
    for (Eigen::Index i = 0; i < dofs; ++i)
      if (!free[std::size_t(i)]) res[i] = beff[i] = 0;
    st.relative_residual = beff.norm() > 0 ? res.norm() / beff.norm() : res.norm();
  } else {
    // Taylor-Hood: pressure unknowns of the vertices with tets; the others stay 0.
    const auto np = Eigen::Index(p2_.corner_slots);
    std::vector<std::uint8_t> active(std::size_t(np), 0);
    for (TetId t : mesh_->tets())
      for (VertexId v : mesh_->tet_vertices(t)) active[v.idx()] = 1;
    // -C / c, and the lumped pressure preconditioner.
    Triplets ct;
    Eigen::VectorXd pdiag = Eigen::VectorXd::Zero(np);
    for (TetId t : mesh_->tets()) {
      const double vol = tets_[t.idx()].volume, il = inv_lambda_[t.idx()];
      const auto& v = mesh_->tet_vertices(t);
      for (int i = 0; i < 4; ++i) {
        pdiag[Eigen::Index(v[std::size_t(i)].idx())] += vol / 4 * (1 / mu_[t.idx()] + il) / c;
        for (int j = 0; j < 4; ++j)
          ct.emplace_back(int(v[std::size_t(i)].idx()), int(v[std::size_t(j)].idx()), -il * vol / 20 * (i == j ? 2 : 1) / c);
      }
    }
    Eigen::SparseMatrix<double> cm(np, np);
    cm.setFromTriplets(ct.begin(), ct.end());
    // Reduced numbering: free displacements, then active pressures.
    std::vector<Eigen::Index> map(std::size_t(dofs + np), -1);
    Eigen::Index n = 0;
    for (Eigen::Index i = 0; i < dofs; ++i)
      if (free[std::size_t(i)]) map[std::size_t(i)] = n++;
    const Eigen::Index nu = n;
    for (Eigen::Index i = 0; i < np; ++i)
      if (active[std::size_t(i)]) map[std::size_t(dofs + i)] = n++;
    Eigen::VectorXd rb(n);
    const Eigen::VectorXd ru = rhs - k * xk, rp = c_r - d * xk;
    for (Eigen::Index i = 0; i < dofs; ++i)
      if (map[std::size_t(i)] >= 0) rb[map[std::size_t(i)]] = ru[i];
    for (Eigen::Index i = 0; i < np; ++i)
      if (map[std::size_t(dofs + i)] >= 0) rb[map[std::size_t(dofs + i)]] = rp[i];
    Triplets st_t;
    auto add = [&](const Eigen::SparseMatrix<double>& m, Eigen::Index ro, Eigen::Index co, bool transpose) {
      for (Eigen::Index col = 0; col < m.outerSize(); ++col)
        for (Eigen::SparseMatrix<double>::InnerIterator it(m, col); it; ++it) {
          const Eigen::Index i = map[std::size_t(ro + it.row())], j = map[std::size_t(co + it.col())];
          if (i < 0 || j < 0) continue;
          if (transpose) st_t.emplace_back(int(j), int(i), it.value());
          else st_t.emplace_back(int(i), int(j), it.value());
        }
    };
    add(k, 0, 0, false);
    add(d, dofs, 0, false);
    add(d, dofs, 0, true);
    add(cm, dofs, dofs, false);
    Eigen::SparseMatrix<double> s(n, n);
    s.setFromTriplets(st_t.begin(), st_t.end());
    Eigen::VectorXd y = Eigen::VectorXd::Zero(n);
    if (opt_.direct) {
      // Kept like the displacement block's factor: linear tets, the same a, c and constraints.
      if (kind_ != FemKind::Linear || !lu_ || lu_->free != free || lu_->a != a || lu_->c != c) {
        lu_ = std::make_unique<CachedLu>();
        lu_->lu.compute(s);
        if (lu_->lu.info() != Eigen::Success) {
          lu_.reset();
          throw Error("quadratic tets (Taylor-Hood): the saddle-point system is singular (too few constraints, or a "
                      "pressure free to float under fully prescribed displacements?)");
        }
        lu_->free = free;
        lu_->a = a;
        lu_->c = c;
      }
      y = lu_->lu.solve(rb);
    } else {
      // Start from the last pressure and the given displacement.
      for (Eigen::Index i = 0; i < dofs; ++i)
        if (map[std::size_t(i)] >= 0) y[map[std::size_t(i)]] = x[i];
      for (Eigen::Index i = 0; i < np; ++i)
        if (map[std::size_t(dofs + i)] >= 0) y[map[std::size_t(dofs + i)]] = c * pressure_[i];
      // Displacement block preconditioner on the reduced unknowns.
      const Eigen::SparseMatrix<double> kuu = s.topLeftCorner(nu, nu);
      const DirectSolver* ku_factor = nullptr;
      Eigen::VectorXd dinv = kuu.diagonal().cwiseInverse();
      Eigen::VectorXd pinv(n - nu);
      for (Eigen::Index i = 0; i < np; ++i)
        if (map[std::size_t(dofs + i)] >= 0) pinv[map[std::size_t(dofs + i)] - nu] = 1 / pdiag[i];
      const auto precondition = [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) {
        z.resize(r.size());
        if (ku_factor) {
          Eigen::VectorXd zu = Eigen::VectorXd::Zero(nu);
          ku_factor->solve(r.head(nu), zu);
          z.head(nu) = zu;
        } else if (opt_.preconditioner == Preconditioner::None) {
          z.head(nu) = r.head(nu);
        } else {
          z.head(nu) = dinv.cwiseProduct(r.head(nu));  // Jacobi (block-Jacobi: its diagonal, on the reduced block)
        }
        z.tail(n - nu) = pinv.cwiseProduct(r.tail(n - nu));
      };
      const auto apply = [&](const Eigen::VectorXd& v, Eigen::VectorXd& out) { out = s * v; };
      double estimate = 0;
      // As CG: an earlier frame's factor gets stale_limit() iterations, then a fresh one.
      for (int attempt = 0; attempt < 2; ++attempt) {
        const bool reused = attempt == 0 && opt_.preconditioner == Preconditioner::Cholesky && reusable(free, a, c);
        if (opt_.preconditioner == Preconditioner::Cholesky) {
          if (!reused) factor_.reset();
          // Keyed by the full mask: the reduced block's numbering follows it.
          ku_factor = &factor(kuu, std::vector<std::uint8_t>(std::size_t(nu), 1), free, a, c).solver;
        }
        const int its =
            minres(apply, precondition, rb, y, opt_.tolerance, reused ? stale_limit() : opt_.max_iterations, estimate);
        st.iterations += its;
        if (opt_.preconditioner == Preconditioner::Cholesky && !reused) factor_->fresh_iterations = its;
        if (estimate <= opt_.tolerance || !reused) break;
      }
      if (!(estimate <= opt_.tolerance)) st.message = "quadratic tets: minres: not converged within the iteration cap";
    }
    const Eigen::VectorXd res = rb - s * y;
    st.relative_residual = rb.norm() > 0 ? res.norm() / rb.norm() : res.norm();
    for (Eigen::Index i = 0; i < dofs; ++i)
      if (map[std::size_t(i)] >= 0) x[i] = y[map[std::size_t(i)]];
    for (Eigen::Index i = 0; i < np; ++i)
      pressure_[i] = map[std::size_t(dofs + i)] >= 0 ? y[map[std::size_t(dofs + i)]] / c : 0.0;
  }
  st.converged = st.message.empty() && x.allFinite();
  if (!x.allFinite() && st.message.empty()) st.message = "quadratic tets: NaN/Inf in the solution";
  st.solve_ms = ms_since(t0);
  return st;
}

std::vector<double> QuadraticSolver::von_mises(const Eigen::VectorXd& u) const {
  std::vector<double> out(mesh_->tet_capacity(), 0.0);
  const Eigen::Vector4d centre = Eigen::Vector4d::Constant(0.25);
  for (TetId t : mesh_->tets()) {
    const std::size_t ti = t.idx();
    const auto& n = p2_.tets[ti];
    Eigen::Matrix<double, 30, 1> ue;
    for (int a = 0; a < 10; ++a) ue.segment<3>(3 * a) = u.segment<3>(3 * Eigen::Index(n[std::size_t(a)]));
    const Eigen::Matrix3d h = p2_displacement_gradient(tets_[ti], ue, centre);
    Eigen::Matrix3d eps;
    if (kind_ == FemKind::Corotational) {
      Eigen::Matrix3d f = Eigen::Matrix3d::Identity();
      for (int i = 0; i < 4; ++i) f += ue.segment<3>(3 * i) * tets_[ti].grad_l.row(i);
      const Eigen::Matrix3d r = polar_rotation(f), g = r.transpose() * (Eigen::Matrix3d::Identity() + h);
      eps = 0.5 * (g + g.transpose()) - Eigen::Matrix3d::Identity();
    } else {
      eps = 0.5 * (h + h.transpose());
    }
    // The pressure does not change von Mises: the deviatoric stress 2 mu dev(eps) is enough.
    out[ti] = von_mises_of(2 * mu_[ti] * eps);
  }
  return out;
}

}  // namespace incise
