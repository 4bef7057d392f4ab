#include "sim/fem/mixed_solver.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include <Eigen/SparseLU>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "mesh/clock.h"
#include "mesh/errors.h"
#include "sim/petsc/petsc_saddle.h"

namespace incise {

namespace {

void check_mixed_material(const Material& m, const std::string& what) {
  // The standard check, but 0.5 itself is allowed: the pressure carries the constraint.
  Material probe = m;
  if (probe.poisson == 0.5) probe.poisson = 0.25;
  check_material(probe, what);
}

bool same_vector(const Eigen::VectorXd& a, const Eigen::VectorXd& b) { return a.size() == b.size() && a == b; }

template <class F>
void parallel_range(std::size_t n, std::size_t grain, F&& f) {
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) f(i);
  });
}

}  // namespace

// ---- materials --------------------------------------------------------------------

MixedMaterials::MixedMaterials(const MaterialTable& table) {
  default_ = table.fallback();
  has_default_ = table.has_default();
  by_label_ = table.by_label();
}

void MixedMaterials::set_default(const Material& m) {
  check_mixed_material(m, "materials.*");
  default_ = m;
  has_default_ = true;
}

void MixedMaterials::set(int label, const Material& m) {
  check_mixed_material(m, "materials." + std::to_string(label));
  by_label_[label] = m;
}

const Material& MixedMaterials::get(int label) const {
  auto it = by_label_.find(label);
  if (it != by_label_.end()) return it->second;
  if (!has_default_) throw InvalidArgument("materials: no material for region label " + std::to_string(label));
  return default_;
}

MaterialTable MixedMaterials::deviatoric_table() const {
  // young' = 2 mu with poisson' = 0 gives mu' = mu and lambda' = 0.
  auto dev = [](const Material& m) { return Material{2 * m.mu(), 0.0, m.density}; };
  MaterialTable t(dev(default_));
  if (!has_default_) t.clear_default();
  for (const auto& [label, m] : by_label_) t.set(label, dev(m));
  return t;
}

double inverse_lambda(const Material& m) {
  const double cap = 1e8 / m.mu();
  if (m.poisson <= 0) return cap;
  return std::min(cap, (1 + m.poisson) * (1 - 2 * m.poisson) / (m.young * m.poisson));
}

// ---- MINRES state -----------------------------------------------------------------

// Preconditioned MINRES (Lanczos in the P^-1 inner product, QR by Givens rotations), kept
// between calls so that a budgeted solve resumes its own iteration.
struct MixedSolver::Krylov {
  bool valid = false;
  std::uint64_t version = 0;
  std::vector<std::uint8_t> mask;
  Eigen::VectorXd b, x;  // the problem and the iterate it returned (resume check)
  Eigen::VectorXd v_old, v, z, w_old, w, az, v_new;
  double gamma_old = 1, gamma = 0, eta = 0, c_old = 1, c = 1, s_old = 0, s = 0, bnorm = 0;
  int iterations = 0;
};

// a M + c K_mu with its diagonal and vertex blocks, what the displacement preconditioners read.
class MixedSolver::UBlock : public LinearOperator {
public:
  UBlock(const FemModel& k, double a, double c) : k_(k), a_(a), c_(c) {
    const Eigen::VectorXd& m = k.lumped_mass();
    diag_ = c * k.diagonal() + a * m;
    const auto& kb = k.diagonal_blocks();
    blocks_.resize(kb.size());
    for (std::size_t v = 0; v < kb.size(); ++v)
      blocks_[v] = c * kb[v] + a * m[Eigen::Index(3 * v)] * Eigen::Matrix3d::Identity();
  }
  Eigen::Index rows() const override { return k_.rows(); }
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const override {
    k_.multiply(x, y);
    y = c_ * y + a_ * k_.lumped_mass().cwiseProduct(x);
  }
  const Eigen::VectorXd& diagonal() const override { return diag_; }
  const std::vector<Eigen::Matrix3d>& diagonal_blocks() const override { return blocks_; }

private:
  const FemModel& k_;
  double a_, c_;
  Eigen::VectorXd diag_;
  std::vector<Eigen::Matrix3d> blocks_;
};

// ---- construction and updates -------------------------------------------------------

MixedSolver::MixedSolver(const TetMesh& mesh, const MixedMaterials& materials, FemKind kind, const MixedOptions& options)
    : mesh_(&mesh), materials_(materials), kind_(kind), opt_(options),
      model_(mesh, materials.deviatoric_table(), kind, Formulation::Standard, options.edge_smoothed),
      krylov_(std::make_unique<Krylov>()) {
  grow();
  parallel_range(mesh.tet_capacity(), 256, [&](std::size_t t) { compute_tet(std::uint32_t(t)); });
  parallel_range(mesh.vertex_capacity(), 512, [&](std::size_t v) { compute_vertex(std::uint32_t(v)); });
  amg_ = std::make_unique<AggregationAmg>(model_, opt_.amg);
}

MixedSolver::~MixedSolver() = default;

void MixedSolver::set_options(const MixedOptions& o) {
  if (o.edge_smoothed != opt_.edge_smoothed)
    throw InvalidArgument("mixed: edge_smoothed is chosen when the solver is made (its model is built for it)");
  const bool new_amg = o.amg.ring != opt_.amg.ring || o.amg.cycle != opt_.amg.cycle || o.amg.rotations != opt_.amg.rotations;
  opt_ = o;
  if (new_amg) amg_ = std::make_unique<AggregationAmg>(model_, opt_.amg);
  pc_version_ = 0;
  krylov_->valid = false;
}

void MixedSolver::grow() {
  const std::size_t nt = mesh_->tet_capacity(), nv = model_.vertex_slots();
  if (rg_.size() < nt) {
    rg_.resize(nt, Eigen::Matrix<double, 3, 4>::Zero());
    invlam_.resize(nt, 0.0);
    rtrace_.resize(nt, 0.0);
    cdiag_.resize(nt, 0.0);
    coff_.resize(nt, 0.0);
    corner_.resize(4 * nt, Eigen::Vector4d::Zero());
  }
  if (corner_slots_.size() < nv) corner_slots_.resize(nv);
  if (std::size_t(pdiag_.size()) < nv) {
    const Eigen::Index old = pdiag_.size();
    pdiag_.conservativeResize(Eigen::Index(nv));
    p_.conservativeResize(Eigen::Index(nv));
    pdiag_.tail(Eigen::Index(nv) - old).setZero();
    p_.tail(Eigen::Index(nv) - old).setZero();
  }
}

void MixedSolver::compute_tet(std::uint32_t t) {
  const TetId id(t);
  if (!model_.tet_alive(id)) {
    rg_[t].setZero();
    return;
  }
  const Eigen::Matrix3d& bm = model_.tet_shape_matrix(id);  // row j-1: grad N_j
  const Eigen::Matrix3d r = model_.rotation(id);
  const double q = model_.tet_volume(id) / 4;
  rg_[t].col(0) = -q * r * (bm.row(0) + bm.row(1) + bm.row(2)).transpose();
  for (int j = 1; j < 4; ++j) rg_[t].col(j) = q * r * bm.row(j - 1).transpose();
  invlam_[t] = inverse_lambda(materials_.get(mesh_->label(id)));
  // (C_t p)_v = cdiag p_v + coff sum(p) with C_t = (M_t - V/16 1 1^T) / mu + M_t / lambda,
  // M_t = V/20 (I + 1 1^T).
  const double vol = model_.tet_volume(id), mu = model_.tet_mu(id);
  cdiag_[t] = vol / 20 * (1 / mu + invlam_[t]);
  coff_[t] = vol * (invlam_[t] / 20 - 1 / (80 * mu));
  rtrace_[t] = kind_ == FemKind::Corotational ? r.trace() - 3 : 0.0;
}

void MixedSolver::compute_vertex(std::uint32_t v) {
  // Lumped pressure mass weighted by (1/mu + 1/lambda): the Schur complement's scale per tet.
  double d = 0;
  corner_slots_[v].clear();
  if (mesh_->is_alive(VertexId(v)))
    for (TetId t : mesh_->incident_tets(VertexId(v))) {
      d += model_.tet_volume(t) / 4 * (1 / model_.tet_mu(t) + invlam_[t.idx()]);
      corner_slots_[v].push_back(4 * t.idx() + std::uint32_t(mesh_->local_index(t, VertexId(v))));
    }
  pdiag_[v] = d;
}

void MixedSolver::apply(const TopologyChange& change) {
  if (change.empty()) return;
  model_.apply(change);
  grow();
  for (TetId t : change.added_tets) compute_tet(t.idx());
  for (TetId t : change.removed_tets)
    if (!mesh_->is_alive(t)) rg_[t.idx()].setZero();
  // The kept pressure follows the vertices like the displacement does (a warm start).
  auto interpolate = [&](const VertexOrigin& o) {
    p_[o.vertex.idx()] = interpolate_origin(o, 0.0, [&](VertexId q) { return p_[q.idx()]; });
  };
  for (const VertexOrigin& o : change.added_vertices) interpolate(o);
  for (const VertexOrigin& o : change.moved_vertices) interpolate(o);
  for (VertexId v : change.removed_vertices) p_[v.idx()] = 0;
  for (VertexId v : change.touched_vertices) compute_vertex(v.idx());
  for (TetId t : change.added_tets)
    for (std::uint32_t v : model_.tet_vertex_ids(t)) compute_vertex(v);
  amg_->apply(change);
  if (chol_) chol_->apply(change);
  invalidate();
}

void MixedSolver::update_rotations(const Eigen::VectorXd& u) {
  if (kind_ != FemKind::Corotational) return;
  model_.update_rotations(u);
  parallel_range(mesh_->tet_capacity(), 256, [&](std::size_t t) { compute_tet(std::uint32_t(t)); });
  invalidate();
}

void MixedSolver::set_pressure(const Eigen::VectorXd& p) {
  p_.head(std::min(p_.size(), p.size())) = p.head(std::min(p_.size(), p.size()));
  krylov_->valid = false;
}

// ---- operator ---------------------------------------------------------------------

void MixedSolver::multiply_static(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  const Eigen::Index nu = Eigen::Index(num_dofs()), np = Eigen::Index(vertex_slots());
  tmp_u_ = x.head(nu);
  model_.multiply(tmp_u_, scratch_);  // K_mu u
  y.resize(nu + np);
  y.head(nu) = scratch_;
  y.tail(np).setZero();
  // Pass 1, per tet: each corner's share of -B^T p (3) and of -B u - C p (1), written to its
  // own slot (no conflicts).
  parallel_range(mesh_->tet_capacity(), 512, [&](std::size_t t) {
    if (!model_.tet_alive(TetId(std::uint32_t(t)))) return;
    const auto& vs = model_.tet_vertex_ids(TetId(std::uint32_t(t)));
    const Eigen::Matrix<double, 3, 4>& g = rg_[t];
    double div = 0, psum = 0;
    for (int j = 0; j < 4; ++j) {
      div += g.col(j).dot(x.segment<3>(3 * Eigen::Index(vs[j])));
      psum += x[nu + Eigen::Index(vs[j])];
    }
    const double base = -div - coff_[t] * psum;
    for (int j = 0; j < 4; ++j) {
      Eigen::Vector4d& c = corner_[4 * t + std::size_t(j)];
      c.head<3>() = -psum * g.col(j);
      c[3] = base - cdiag_[t] * x[nu + Eigen::Index(vs[j])];
    }
  });
  // Pass 2, per vertex: the sum over its corners.
  parallel_range(std::min<std::size_t>(corner_slots_.size(), std::size_t(np)), 512, [&](std::size_t v) {
    Eigen::Vector4d sum = Eigen::Vector4d::Zero();
    for (std::uint32_t slot : corner_slots_[v]) sum += corner_[slot];
    y.segment<3>(3 * Eigen::Index(v)) += sum.head<3>();
    y[nu + Eigen::Index(v)] = sum[3];
  });
}

void MixedSolver::multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  multiply_static(x, y);
  if (a_ == 0 && c_ == 1) return;
  const Eigen::Index nu = Eigen::Index(num_dofs());
  y *= c_;
  y.head(nu) += a_ * model_.lumped_mass().cwiseProduct(x.head(nu));
}

void MixedSolver::set_system(double mass_coeff, double stiffness_coeff) {
  if (!(mass_coeff >= 0) || !(stiffness_coeff > 0))
    throw InvalidArgument("mixed: system coefficients: expected a >= 0 and c > 0");
  if (mass_coeff == a_ && stiffness_coeff == c_) return;
  a_ = mass_coeff;
  c_ = stiffness_coeff;
  invalidate();
}

Eigen::VectorXd MixedSolver::right_hand_side(const Eigen::VectorXd& f) const {
  const Eigen::Index nu = Eigen::Index(num_dofs()), np = Eigen::Index(vertex_slots());
  Eigen::VectorXd b = Eigen::VectorXd::Zero(nu + np);
  b.head(std::min(nu, f.size())) = f.head(std::min(nu, f.size()));
  if (kind_ != FemKind::Corotational) return b;
  Eigen::VectorXd bu = Eigen::VectorXd::Zero(nu);
  model_.add_rotation_rhs(bu);
  b.head(nu) += bu;
  // c_R: the constant part of the rotated volumetric strain, V/4 (tr R - 3) per corner.
  for (std::size_t t = 0; t < rtrace_.size(); ++t) {
    if (!model_.tet_alive(TetId(std::uint32_t(t)))) continue;
    const double c = model_.tet_volume(TetId(std::uint32_t(t))) / 4 * rtrace_[t];
    for (std::uint32_t v : model_.tet_vertex_ids(TetId(std::uint32_t(t)))) b[nu + Eigen::Index(v)] += c;
  }
  return b;
}

Eigen::SparseMatrix<double> MixedSolver::assemble() const {
  const Eigen::Index nu = Eigen::Index(num_dofs()), np = Eigen::Index(vertex_slots());
  const Eigen::SparseMatrix<double> k = model_.assemble();
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(std::size_t(k.nonZeros()) + 40 * mesh_->num_tets());
  for (Eigen::Index c = 0; c < k.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(k, c); it; ++it) trip.emplace_back(it.row(), it.col(), it.value());
  for (std::size_t t = 0; t < rg_.size(); ++t) {
    const TetId id{std::uint32_t(t)};
    if (!model_.tet_alive(id)) continue;
    const auto& vs = model_.tet_vertex_ids(id);
    const double vol = model_.tet_volume(id), mu = model_.tet_mu(id);
    for (int i = 0; i < 4; ++i) {
      const Eigen::Index pi = nu + Eigen::Index(vs[i]);
      for (int j = 0; j < 4; ++j) {
        for (int d = 0; d < 3; ++d) {
          trip.emplace_back(pi, 3 * Eigen::Index(vs[j]) + d, -rg_[t](d, j));
          trip.emplace_back(3 * Eigen::Index(vs[j]) + d, pi, -rg_[t](d, j));
        }
        const double m = vol / 20 * (i == j ? 2 : 1);
        trip.emplace_back(pi, nu + Eigen::Index(vs[j]), -((m - vol / 16) / mu + m * invlam_[t]));
      }
    }
  }
  Eigen::SparseMatrix<double> a(nu + np, nu + np);
  a.setFromTriplets(trip.begin(), trip.end());
  if (a_ == 0 && c_ == 1) return a;
  a *= c_;
  const Eigen::VectorXd& m = model_.lumped_mass();
  for (Eigen::Index i = 0; i < nu; ++i)
    if (m[i] != 0) a.coeffRef(i, i) += a_ * m[i];
  return a;
}

double MixedSolver::volume_change(const Eigen::VectorXd& u) const {
  double dv = 0;
  for (std::size_t t = 0; t < rg_.size(); ++t) {
    const TetId id{std::uint32_t(t)};
    if (!model_.tet_alive(id)) continue;
    const auto& vs = model_.tet_vertex_ids(id);
    for (int j = 0; j < 4; ++j) dv += 4 * rg_[t].col(j).dot(u.segment<3>(3 * Eigen::Index(vs[j])));
    dv += model_.tet_volume(id) * rtrace_[t];
  }
  return dv;
}

// ---- constraints and preconditioner ------------------------------------------------------

void MixedSolver::full_mask(const std::vector<std::uint8_t>& free) {
  const std::size_t nu = num_dofs(), np = vertex_slots();
  mask_.assign(nu + np, 0);
  umask_.assign(nu, 0);
  const Eigen::VectorXd& kd = model_.diagonal();
  // Unknowns without tets (zero rows) are kept at 0 whatever the caller says.
  for (std::size_t i = 0; i < nu; ++i) umask_[i] = mask_[i] = (i < free.size() && free[i] && kd[Eigen::Index(i)] > 0);
  for (std::size_t v = 0; v < np; ++v) mask_[nu + v] = pdiag_[Eigen::Index(v)] > 0;
}

void MixedSolver::setup_preconditioner() {
  // At a fresh start after the operator or the constraints changed (a multigrid patch after a
  // topology change happens here too); the asynchronous factor at every fresh start (it adopts
  // a finished factorization only then, so a resumed iteration keeps its preconditioner).
  const bool changed = pc_version_ != version_ || pc_mask_ != mask_;
  use_chol_ = opt_.preconditioner == MixedPreconditioner::Cholesky && !opt_.direct;
  if (!changed && !use_chol_) return;
  if (pc_mask_ != mask_) {
    amg_->mark_stale();
    if (chol_) chol_->mark_stale();
  }
  if (changed) ublock_ = std::make_unique<UBlock>(model_, a_, c_);
  // The multigrid's coarse space holds only vertices with all three unknowns free, and it
  // cannot be built without one (rollers on every vertex of a thin mesh); the direct path only
  // measures residuals with it: block-Jacobi is enough there.
  bool amg_ok = false;
  for (std::size_t v = 0; v < vertex_slots() && !amg_ok; ++v)
    amg_ok = umask_[3 * v] && umask_[3 * v + 1] && umask_[3 * v + 2];
  use_amg_ = opt_.preconditioner == MixedPreconditioner::Amg && !opt_.direct && amg_ok;
  if (use_chol_) {
    if (!chol_) {
      AsyncCholeskyOptions co = opt_.cholesky;
      if (opt_.budget_ms > 0) co.wait_for_first = false;
      chol_ = std::make_unique<AsyncCholesky>(model_, co);
    }
    const bool moving = amg_ok && opt_.cholesky.settle_with_amg;
    chol_->set_moving(moving ? amg_.get() : nullptr);
    if (moving) amg_->frame(a_, c_, last_iterations_);
    chol_->frame(umask_, a_, c_, last_iterations_);
    chol_->setup(*ublock_, &umask_);
  } else if (use_amg_) {
    amg_->frame(a_, c_, last_iterations_);
    amg_->setup(*ublock_, &umask_);
  } else {
    jacobi_.setup(*ublock_, &umask_);
  }
  if (changed) pressure_preconditioner();
  pc_version_ = version_;
  pc_mask_ = mask_;
}

void MixedSolver::pressure_preconditioner() {
  const std::size_t nu = num_dofs(), np = vertex_slots();
  Eigen::VectorXd d = c_ * pdiag_;
  if (a_ > 0) {
    // c^2 diag(B D^-1 B^T), D = diag(a M + c K): for small c the Schur complement is mostly
    // c^2 B (a M)^-1 B^T, a Laplacian the mass-like term alone misses.
    const Eigen::VectorXd& du = ublock_->diagonal();
    for (std::size_t t = 0; t < rg_.size(); ++t) {
      const TetId id{std::uint32_t(t)};
      if (!model_.tet_alive(id)) continue;
      const auto& vs = model_.tet_vertex_ids(id);
      double sum = 0;
      for (int j = 0; j < 4; ++j)
        for (int k = 0; k < 3; ++k) {
          const std::size_t i = 3 * std::size_t(vs[j]) + std::size_t(k);
          if (umask_[i]) sum += rg_[t](k, j) * rg_[t](k, j) / du[Eigen::Index(i)];
        }
      for (std::uint32_t v : vs) d[v] += c_ * c_ * sum;
    }
  }
  pinv_ = Eigen::VectorXd::Zero(Eigen::Index(np));
  for (std::size_t v = 0; v < np; ++v)
    if (mask_[nu + v] && d[Eigen::Index(v)] > 0) pinv_[Eigen::Index(v)] = 1 / d[Eigen::Index(v)];
}

void MixedSolver::project(Eigen::VectorXd& v) const {
  for (Eigen::Index i = 0; i < v.size(); ++i)
    if (!mask_[std::size_t(i)]) v[i] = 0;
}

void MixedSolver::precondition(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  const Eigen::Index nu = Eigen::Index(num_dofs()), np = Eigen::Index(vertex_slots());
  tmp_u_ = r.head(nu);
  if (use_chol_) chol_->apply(tmp_u_, tmp_z_);
  else if (use_amg_) amg_->apply(tmp_u_, tmp_z_);
  else jacobi_.apply(tmp_u_, tmp_z_);
  z.resize(nu + np);
  z.head(nu) = tmp_z_;
  z.tail(np) = r.tail(np).cwiseProduct(pinv_);
}

double MixedSolver::preconditioned_norm(const Eigen::VectorXd& r) const {
  Eigen::VectorXd z;
  precondition(r, z);
  return std::sqrt(std::max(0.0, r.dot(z)));
}

double MixedSolver::relative_residual(const Eigen::VectorXd& b, const Eigen::VectorXd& x) const {
  Eigen::VectorXd r;
  multiply(x, r);
  r = b - r;
  project(r);
  return krylov_->bnorm > 0 ? preconditioned_norm(r) / krylov_->bnorm : 0.0;
}

// ---- solves -------------------------------------------------------------------------

MixedStats MixedSolver::solve(const Eigen::VectorXd& f, const std::vector<std::uint8_t>& free, Eigen::VectorXd& u) {
  if (a_ != 0 || c_ != 1) throw InvalidArgument("mixed: solve() is the static solve; set_system(0, 1) or solve_system()");
  const Eigen::Index nu = Eigen::Index(num_dofs()), np = Eigen::Index(vertex_slots());
  if (u.size() < nu) {  // slots added by growth start at 0
    const Eigen::Index old = u.size();
    u.conservativeResize(nu);
    u.tail(nu - old).setZero();
  }
  Eigen::VectorXd x(nu + np);
  x.head(nu) = u.head(nu);
  x.tail(np) = p_;
  MixedStats st = solve_system(right_hand_side(f), free, x);
  u.head(nu) = x.head(nu);
  p_ = x.tail(np);
  return st;
}

MixedStats MixedSolver::solve_system(const Eigen::VectorXd& b, const std::vector<std::uint8_t>& free, Eigen::VectorXd& x) {
  const Eigen::Index nu = Eigen::Index(num_dofs()), np = Eigen::Index(vertex_slots());
  if (b.size() != nu + np || x.size() != nu + np)
    throw InvalidArgument("mixed: solve_system: b and x need num_dofs() + vertex_slots() entries");
  full_mask(free);
  for (Eigen::Index v = 0; v < np; ++v)
    if (!mask_[std::size_t(nu + v)]) x[nu + v] = 0;
  return opt_.direct ? solve_direct(b, x) : solve_minres(b, x);
}

MixedStats MixedSolver::solve_direct(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  const double t0 = now_ms();
  MixedStats st;
  const Eigen::SparseMatrix<double> a = assemble();
  // Prescribed values to the right-hand side; the system on the free unknowns only.
  Eigen::VectorXd xk = x;
  for (Eigen::Index i = 0; i < x.size(); ++i)
    if (mask_[std::size_t(i)]) xk[i] = 0;
  const Eigen::VectorXd rhs = b - a * xk;
  std::vector<Eigen::Index> index(std::size_t(x.size()), -1);
  Eigen::Index n = 0;
  for (Eigen::Index i = 0; i < x.size(); ++i)
    if (mask_[std::size_t(i)]) index[std::size_t(i)] = n++;
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(std::size_t(a.nonZeros()));
  for (Eigen::Index c = 0; c < a.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(a, c); it; ++it) {
      const Eigen::Index r = index[std::size_t(it.row())], cc = index[std::size_t(it.col())];
      if (r >= 0 && cc >= 0) trip.emplace_back(r, cc, it.value());
    }
  Eigen::SparseMatrix<double> af(n, n);
  af.setFromTriplets(trip.begin(), trip.end());
  Eigen::VectorXd bf(n);
  for (Eigen::Index i = 0; i < x.size(); ++i)
    if (index[std::size_t(i)] >= 0) bf[index[std::size_t(i)]] = rhs[i];
  Eigen::VectorXd xf(n);
  bool iterative_converged = true;  // PETSc's MINRES met its tolerance
  if (opt_.petsc) {
    // The free displacements come first in af, then the free pressures (index keeps the order).
    setup_preconditioner();
    const Eigen::Index nu_all = Eigen::Index(num_dofs());
    Eigen::Index nu = 0;
    Eigen::VectorXd pd(n);
    for (Eigen::Index i = 0; i < x.size(); ++i) {
      const Eigen::Index k = index[std::size_t(i)];
      if (k < 0) continue;
      xf[k] = x[i];
      if (i < nu_all) ++nu;
      else pd[k] = pdiag_[i - nu_all];
    }
    const PetscSaddleStats ps = petsc_solve_saddle(af, nu, pd.tail(n - nu), bf, xf, opt_.tolerance, opt_.max_iterations,
                                                   opt_.petsc_options);
    st.iterations = st.total_iterations = ps.iterations;
    iterative_converged = ps.converged;
  } else {
    Eigen::SparseLU<Eigen::SparseMatrix<double>> lu;
    lu.compute(af);
    if (lu.info() != Eigen::Success) {
      st.breakdown = true;
      st.solve_ms = now_ms() - t0;
      return st;
    }
    xf = lu.solve(bf);
  }
  for (Eigen::Index i = 0; i < x.size(); ++i)
    if (index[std::size_t(i)] >= 0) x[i] = xf[index[std::size_t(i)]];
  // The residual in the iterative solver's measure, so the two compare.
  setup_preconditioner();
  Eigen::VectorXd r;
  multiply(xk, r);
  r = b - r;
  project(r);
  krylov_->valid = false;
  krylov_->bnorm = preconditioned_norm(r);
  st.relative_residual = relative_residual(b, x);
  st.breakdown = !std::isfinite(st.relative_residual);
  st.converged = !st.breakdown && iterative_converged;
  st.solve_ms = now_ms() - t0;
  return st;
}

MixedStats MixedSolver::solve_minres(const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  const double t0 = now_ms();
  MixedStats st;
  Krylov& k = *krylov_;
  const bool resume = k.valid && k.version == version_ && k.mask == mask_ && same_vector(k.b, b) && same_vector(k.x, x);
  st.resumed = resume;
  auto left = [&] { return opt_.budget_ms > 0 ? opt_.budget_ms - (now_ms() - t0) : 1e300; };
  double iter_ms = 0;  // measured cost of one iteration, to stop before the budget runs out
  bool fresh = !resume;
  while (true) {
    if (fresh) {
      const double ts = now_ms();
      setup_preconditioner();
      st.setup_ms += now_ms() - ts;
      // ||b_eff||: the right-hand side with the prescribed values moved over. A x_kept is
      // cached: frames whose loads change but not their prescribed values skip that product.
      Eigen::VectorXd xk = x;
      for (Eigen::Index i = 0; i < x.size(); ++i)
        if (mask_[std::size_t(i)]) xk[i] = 0;
      if (!(akept_version_ == version_ && same_vector(kept_, xk))) {
        kept_ = xk;
        multiply(xk, akept_);
        akept_version_ = version_;
      }
      Eigen::VectorXd r = b - akept_;
      project(r);
      k.bnorm = preconditioned_norm(r);
      multiply(x, r);
      r = b - r;
      project(r);
      k.v_old = Eigen::VectorXd::Zero(r.size());
      k.v = r;
      precondition(k.v, k.z);
      k.gamma = std::sqrt(std::max(0.0, k.v.dot(k.z)));
      k.gamma_old = 1;
      k.eta = k.gamma;
      k.c_old = k.c = 1;
      k.s_old = k.s = 0;
      k.w_old = k.w = Eigen::VectorXd::Zero(r.size());
      k.iterations = 0;
      k.mask = mask_;
      k.version = version_;
      if (st.iterations == 0) st.initial_relative_residual = k.bnorm > 0 ? k.gamma / k.bnorm : 0.0;
      fresh = false;
    }
    const double target = opt_.tolerance * k.bnorm;
    while (std::abs(k.eta) > target && k.gamma > 0 && st.iterations < opt_.max_iterations) {
      // 1.25: iterations vary (shared cores); stopping one early beats overrunning the frame.
      if (st.iterations > 0 && left() < 1.25 * iter_ms) {
        st.budget_exhausted = true;
        break;
      }
      const double ti = now_ms();
      k.z /= k.gamma;
      multiply(k.z, k.az);
      project(k.az);
      const double delta = k.az.dot(k.z);
      k.v_new = k.az - (delta / k.gamma) * k.v - (k.gamma / k.gamma_old) * k.v_old;
      k.v_old.swap(k.v);
      k.v.swap(k.v_new);  // v: the new Lanczos vector
      Eigen::VectorXd z_new;
      precondition(k.v, z_new);
      const double g2 = k.v.dot(z_new);
      if (!(g2 >= 0) || !std::isfinite(g2)) {
        st.breakdown = true;
        break;
      }
      const double gamma_new = std::sqrt(g2);
      const double a0 = k.c * delta - k.c_old * k.s * k.gamma;
      const double a1 = std::hypot(a0, gamma_new);
      const double a2 = k.s * delta + k.c_old * k.c * k.gamma;
      const double a3 = k.s_old * k.gamma;
      const double c_new = a0 / a1, s_new = gamma_new / a1;
      Eigen::VectorXd w_new = (k.z - a3 * k.w_old - a2 * k.w) / a1;
      x += (c_new * k.eta) * w_new;
      k.eta = -s_new * k.eta;
      k.w_old.swap(k.w);
      k.w.swap(w_new);
      k.z.swap(z_new);
      k.gamma_old = k.gamma;
      k.gamma = gamma_new;
      k.c_old = k.c;
      k.c = c_new;
      k.s_old = k.s;
      k.s = s_new;
      ++st.iterations;
      ++k.iterations;
      const double dt = now_ms() - ti;
      iter_ms = iter_ms == 0 ? dt : std::max(dt, 0.8 * iter_ms + 0.2 * dt);
    }
    if (st.breakdown) break;
    // A budgeted stop reports the recurrence's estimate (exact in exact arithmetic): the true
    // residual costs a product and a preconditioner application the budget did not leave.
    if (st.budget_exhausted && std::abs(k.eta) > target) {
      st.relative_residual = k.bnorm > 0 ? std::abs(k.eta) / k.bnorm : 0.0;
      break;
    }
    st.relative_residual = relative_residual(b, x);
    st.converged = st.relative_residual <= opt_.tolerance;
    // The recurrence's estimate can drift from the true residual (lost orthogonality): restart
    // from the current iterate while iterations and budget remain.
    if (st.converged || st.budget_exhausted || st.iterations >= opt_.max_iterations || left() < iter_ms) break;
    if (!std::isfinite(st.relative_residual)) {
      st.breakdown = true;
      break;
    }
    fresh = true;
  }
  st.total_iterations = last_iterations_ = k.iterations;
  k.valid = !st.converged && !st.breakdown;
  if (k.valid) {
    k.b = b;
    k.x = x;
  }
  st.solve_ms = now_ms() - t0;
  return st;
}

}  // namespace incise
