#include "sim/fem/fem_simulation.h"

#include <chrono>
#include <cmath>
#include <sstream>

#include <Eigen/Eigenvalues>

#include "mesh/clock.h"
#include "mesh/errors.h"
#include "sim/fem/assembled_stiffness.h"
#include "sim/fem/mixed_solver.h"
#include "sim/petsc/petsc_solver.h"
#include "sim/fem/quadratic_solver.h"

namespace incise {

namespace {

// a * diag(m) + c * K: the backward-Euler system (a = 1 + dt*damping, c = dt^2) or K itself
// (a = 0, c = 1: every call forwards to K, nothing copied).
class ScaledSystem : public LinearOperator {
public:
  ScaledSystem(const LinearOperator& k, const Eigen::VectorXd& mass, double a, double c)
      : k_(k), mass_(mass), a_(a), c_(c) {
    if (is_k()) return;
    diag_ = c_ * k_.diagonal() + a_ * mass_;
    const auto& kb = k_.diagonal_blocks();
    blocks_.resize(kb.size());
    for (std::size_t v = 0; v < kb.size(); ++v)
      blocks_[v] = c_ * kb[v] + a_ * mass_[Eigen::Index(3 * v)] * Eigen::Matrix3d::Identity();
  }
  Eigen::Index rows() const override { return k_.rows(); }
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const override {
    k_.multiply(x, y);
    if (is_k()) return;
    y = c_ * y + a_ * mass_.cwiseProduct(x);
  }
  const Eigen::VectorXd& diagonal() const override { return is_k() ? k_.diagonal() : diag_; }
  const std::vector<Eigen::Matrix3d>& diagonal_blocks() const override {
    return is_k() ? k_.diagonal_blocks() : blocks_;
  }

private:
  bool is_k() const { return a_ == 0 && c_ == 1; }
  const LinearOperator& k_;
  const Eigen::VectorXd& mass_;
  double a_, c_;
  Eigen::VectorXd diag_;
  std::vector<Eigen::Matrix3d> blocks_;
};

// b - A x_held on the free unknowns, zero on the held ones (x_held: x with its free entries
// zeroed): the right-hand side of the free block, for the solvers that eliminate held unknowns.
Eigen::VectorXd lifted_rhs(const LinearOperator& op, const Eigen::VectorXd& b, const Eigen::VectorXd& x,
                           const std::vector<std::uint8_t>& free) {
  Eigen::VectorXd xk = x, ax;
  for (Eigen::Index i = 0; i < xk.size(); ++i)
    if (free[std::size_t(i)]) xk[i] = 0;
  op.multiply(xk, ax);
  ax = b - ax;
  for (Eigen::Index i = 0; i < ax.size(); ++i)
    if (!free[std::size_t(i)]) ax[i] = 0;
  return ax;
}

// The true residual on the free unknowns relative to the lifted right-hand side, so every
// solver's stats compare with CG's.
double free_relative_residual(const LinearOperator& op, const Eigen::VectorXd& b, const Eigen::VectorXd& x,
                              const std::vector<std::uint8_t>& free, const Eigen::VectorXd& lifted) {
  Eigen::VectorXd r;
  op.multiply(x, r);
  r = b - r;
  for (Eigen::Index i = 0; i < r.size(); ++i)
    if (!free[std::size_t(i)]) r[i] = 0;
  const double bn = lifted.norm();
  return bn > 0 ? r.norm() / bn : 0;
}

}  // namespace

FemSimulation::FemSimulation(const TetMesh& mesh, const MaterialTable& materials, const FemSimulationOptions& options)
    : mesh_(&mesh),
      follower_(mesh),
      opt_(options),
      // Mixed: the model holds the deviatoric part (lambda = 0, the standard element), the mixed
      // solver the rest; the model still gives masses, rotations and the stress output.
      // Quadratic: the linear model stays (rigid-mode checks, lumped masses); Taylor-Hood's may
      // hold Poisson's ratio 0.5, so it gets the deviatoric table as Mixed does.
      model_(mesh,
             allows_incompressible(options.formulation) ? MixedMaterials(materials).deviatoric_table() : materials,
             options.kind,
             is_mixed(options.formulation) || is_quadratic(options.formulation) ? Formulation::Standard
                                                                               : options.formulation,
             smooths_edges(options.formulation)),
      cg_(options.cg), materials_(materials) {
  if (!(opt_.dt > 0) || !std::isfinite(opt_.dt)) throw InvalidArgument("fem: dt: expected a positive number");
  if (!(opt_.damping >= 0)) throw InvalidArgument("fem: damping: expected a number >= 0");
  if (opt_.nonlinear_iterations < 1) throw InvalidArgument("fem: nonlinear_iterations: expected an integer >= 1");
  if (opt_.backend == StiffnessBackend::Petsc) {
    if (opt_.method != SolverMethod::Cg) throw InvalidArgument("fem: backend petsc is a solver of its own: method must be cg");
  }
  const InversionBarrierOptions& ib = opt_.inversion_barrier;
  if (!(ib.j_min >= 0 && ib.j_min < 1) || !(ib.stiffness > 0) || !std::isfinite(ib.stiffness))
    throw InvalidArgument("fem: inversion_barrier: expected j_min in [0, 1) and a positive finite stiffness");
  if (ib.j_min > 0 && opt_.kind != FemKind::Corotational)
    throw InvalidArgument("fem: inversion_barrier: for corotational elements only (linear ones have no relinearization)");
  model_.set_inversion_barrier(ib);
  // A relative residual of 1 or more is met by the zero vector: every frame would "converge" at
  // no displacement.
  if (!(opt_.cg.tolerance > 0 && opt_.cg.tolerance < 1))
    throw InvalidArgument("fem: tolerance: expected a relative residual in (0, 1), got " + std::to_string(opt_.cg.tolerance));
  cg_.set_tolerance(opt_.cg.tolerance);
  cg_.set_max_iterations(opt_.cg.max_iterations);
  cg_.set_budget_ms(opt_.cg.budget_ms);
  if (is_mixed(opt_.formulation)) {
    MixedOptions mo;
    mo.edge_smoothed = smooths_edges(opt_.formulation);
    mo.tolerance = opt_.cg.tolerance;
    mo.max_iterations = opt_.cg.max_iterations;
    mo.direct = opt_.method == SolverMethod::Direct || opt_.backend == StiffnessBackend::Petsc;
    mo.petsc = opt_.backend == StiffnessBackend::Petsc;  // MINRES + field split in this process
    mo.petsc_options = opt_.petsc_options;
    mo.amg = opt_.amg;
    mo.preconditioner = opt_.cg.preconditioner == Preconditioner::Cholesky ? MixedPreconditioner::Cholesky
                        : opt_.cg.preconditioner == Preconditioner::Amg    ? MixedPreconditioner::Amg
                                                                           : MixedPreconditioner::BlockJacobi;
    mixed_ = std::make_unique<MixedSolver>(mesh, MixedMaterials(materials), opt_.kind, mo);
  }
  if (is_quadratic(opt_.formulation)) make_quadratic();
  grow();
  for (std::size_t v = 0; v < model_.vertex_slots(); ++v) update_free(std::uint32_t(v));
}

FemSimulation::~FemSimulation() = default;

void FemSimulation::grow() {
  const Eigen::Index n = model_.rows();
  for (Eigen::VectorXd* f : {&u_, &v_, &f_ext_, &target_}) {
    const Eigen::Index old = f->size();
    if (n > old) {
      f->conservativeResize(n);
      f->tail(n - old).setZero();
    }
  }
  constrained_.resize(model_.vertex_slots(), 0);
  free_.resize(std::size_t(n), 0);
}

void FemSimulation::update_free(std::uint32_t v) {
  const VertexId id(v);
  const bool f = v < mesh_->vertex_capacity() && mesh_->is_alive(id) && !mesh_->incident_tets(id).empty();
  for (int a = 0; a < 3; ++a) free_[3 * v + a] = f && !(constrained_[v] >> a & 1u);
}

void FemSimulation::constrain(VertexId v, unsigned axes, const Vec3& d) {
  if (!mesh_->is_alive(v)) throw InvalidArgument("fem: constrain: vertex " + std::to_string(v.idx()) + " is not alive");
  if (axes == 0 || axes > kAllAxes) throw InvalidArgument("fem: constrain: axes must be a non-empty subset of x, y, z");
  const unsigned held = constrained_[v.idx()] | axes;
  if (held != constrained_[v.idx()]) {
    constrained_[v.idx()] = std::uint8_t(held);
    rigid_dirty_ = direct_dirty_ = system_dirty_ = true;
    if (cholesky_) cholesky_->mark_stale();
    if (amg_) amg_->mark_stale();
    update_free(v.idx());
  }
  for (int a = 0; a < 3; ++a)
    if (axes >> a & 1u) target_[3 * Eigen::Index(v.idx()) + a] = d[a];
}

void FemSimulation::release(VertexId v) {
  if (!constrained_[v.idx()]) return;
  constrained_[v.idx()] = 0;
  rigid_dirty_ = direct_dirty_ = system_dirty_ = true;
  if (cholesky_) cholesky_->mark_stale();
  if (amg_) amg_->mark_stale();
  update_free(v.idx());
}

void FemSimulation::reset_state() {
  u_.setZero();
  v_.setZero();
  qu_.setZero();
  qv_.setZero();
}

std::vector<Vec3> FemSimulation::positions() const {
  std::vector<Vec3> p(mesh_->vertex_capacity(), Vec3::Zero());
  for (std::size_t v = 0; v < p.size(); ++v)
    if (mesh_->is_alive(VertexId(std::uint32_t(v)))) p[v] = mesh_->rest(VertexId(std::uint32_t(v))) + u_.segment<3>(3 * v);
  return p;
}

std::vector<double> FemSimulation::von_mises() const {
  if (quadratic_) return quadratic_->von_mises(qu_);
  return model_.von_mises(u_);  // changes nothing: writing stresses must not change the run
}

void FemSimulation::apply(const TopologyChange& change) {
  follower_.follow(*mesh_, change);
  model_.apply(change);
  grow();
  interpolate_added_vertices(change, model_.vertex_slots(), u_);
  interpolate_added_vertices(change, model_.vertex_slots(), v_);
  interpolate_added_vertices(change, model_.vertex_slots(), target_);
  for (const VertexOrigin& o : change.added_vertices) {
    // Held on the axes every parent holds (a vertex split on a symmetry plane stays on it).
    unsigned axes = kAllAxes;
    bool any = false;
    for (int k = 0; k < 4; ++k)
      if (o.parents[k].is_valid() && o.weights[k] != 0) {
        any = true;
        axes &= constrained_[o.parents[k].idx()];
      }
    constrained_[o.vertex.idx()] = std::uint8_t(any ? axes : 0);
    f_ext_.segment<3>(3 * o.vertex.idx()).setZero();  // loads stay on the nodes they were put on
    update_free(o.vertex.idx());
  }
  for (VertexId v : change.removed_vertices) {
    constrained_[v.idx()] = 0;
    f_ext_.segment<3>(3 * v.idx()).setZero();
    // A dead slot moves nowhere: readers of displacement() over every slot see zero there.
    if (3 * Eigen::Index(v.idx()) + 3 <= u_.size()) u_.segment<3>(3 * v.idx()).setZero();
    if (3 * Eigen::Index(v.idx()) + 3 <= v_.size()) v_.segment<3>(3 * v.idx()).setZero();
    update_free(v.idx());
  }
  for (VertexId v : change.touched_vertices) update_free(v.idx());
  // The rigid-mode check is O(mesh), so a topology change does not re-arm it: the per-cut
  // path stays local. A cut that frees a part shows up as a CG breakdown or non-convergence;
  // callers that want the precise diagnosis call check_constraints().
  predictor_.apply(change, model_.vertex_slots());
  if (mixed_) mixed_->apply(change);
  if (quadratic_ && !change.empty()) make_quadratic();
  if (cholesky_) cholesky_->apply(change);
  if (amg_) amg_->apply(change);
  if (!change.empty()) assembled_dirty_ = direct_dirty_ = system_dirty_ = changed_since_frame_ = true;
}

namespace {

// Whether the held components of points (x, axes) block every rigid motion w(x) = t + omega x (x - c):
// each held component is one linear condition on (t, omega), and all six must be pinned. The
// points are centred and scaled to the unit ball so the test does not depend on units; 1e-13 on
// the normal matrix's eigenvalues accepts points 1e-6 of the part's size off a common line.
bool blocks_rigid_motions(const std::vector<std::pair<Vec3, unsigned>>& held) {
  if (held.empty()) return false;
  Vec3 c = Vec3::Zero();
  for (const auto& h : held) c += h.first;
  c /= double(held.size());
  double scale = 0;
  for (const auto& h : held) scale = std::max(scale, (h.first - c).norm());
  if (!(scale > 0)) scale = 1;
  Eigen::Matrix<double, 6, 6> normal = Eigen::Matrix<double, 6, 6>::Zero();
  for (const auto& [x, axes] : held) {
    const Vec3 d = (x - c) / scale;
    for (int a = 0; a < 3; ++a) {
      if (!(axes >> a & 1u)) continue;
      // Component a of t + omega x d: t_a + omega . (d x e_a).
      Eigen::Matrix<double, 6, 1> row = Eigen::Matrix<double, 6, 1>::Zero();
      row[a] = 1;
      row.tail<3>() = d.cross(Vec3::Unit(a));
      normal += row * row.transpose();
    }
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(normal, Eigen::EigenvaluesOnly);
  return eig.eigenvalues()[0] > 1e-13 * eig.eigenvalues()[5];
}

}  // namespace

void FemSimulation::check_rigid_modes() const {
  // Face-connected parts; the constrained components of each must block all six rigid motions.
  const TetMesh& m = *mesh_;
  std::vector<std::int32_t> part(m.tet_capacity(), -1);
  std::vector<std::uint32_t> stack;
  std::vector<std::int32_t> vertex_seen(m.vertex_capacity(), -1);
  int nparts = 0, bad = 0;
  std::ostringstream msg;
  for (std::size_t s = 0; s < m.tet_capacity(); ++s) {
    if (!m.is_alive(TetId(std::uint32_t(s))) || part[s] >= 0) continue;
    const int id = nparts++;
    std::vector<std::pair<Vec3, unsigned>> held;
    std::size_t ntets = 0;
    bool rollers = false;
    part[s] = id;
    stack.assign(1, std::uint32_t(s));
    while (!stack.empty()) {
      const TetId t(stack.back());
      stack.pop_back();
      ++ntets;
      for (VertexId v : m.tet_vertices(t))
        if (vertex_seen[v.idx()] != id) {
          vertex_seen[v.idx()] = id;
          if (constrained_[v.idx()]) {
            held.emplace_back(m.rest(v), constrained_[v.idx()]);
            rollers = rollers || constrained_[v.idx()] != kAllAxes;
          }
        }
      for (int f = 0; f < 4; ++f) {
        const TetId n = m.neighbor(t, f);
        if (n.is_valid() && part[n.idx()] < 0) {
          part[n.idx()] = id;
          stack.push_back(n.idx());
        }
      }
    }
    if (!blocks_rigid_motions(held)) {
      if (bad < 3) {
        msg << (bad ? "; " : "") << "part " << id << " (" << ntets << " tets, near ("
            << m.rest(m.tet_vertices(TetId(std::uint32_t(s)))[0]).transpose() << ")) has " << held.size()
            << " constrained vertices";
        if (rollers) msg << ", whose held components leave a rigid motion free";
        else if (held.size() >= 3) msg << ", all on one line";
      }
      ++bad;
    }
  }
  if (bad)
    throw InvalidArgument("static solve is under-constrained: " + std::to_string(bad) + " of " +
                          std::to_string(nparts) + " connected parts can move rigidly: " + msg.str() +
                          "; fix or prescribe at least 3 non-collinear nodes per part (or rollers that block every "
                          "rigid motion), or use a dynamic integrator");
}

void FemSimulation::body_and_external_forces(Eigen::VectorXd& b) const {
  b = f_ext_;
  if (opt_.gravity.squaredNorm() > 0) {
    const Eigen::VectorXd& m = model_.lumped_mass();
    for (Eigen::Index i = 0; i < b.size(); i += 3) b.segment<3>(i) += m[i] * opt_.gravity;
  }
}

void FemSimulation::solve_system(const LinearOperator& k, double a, double c, const Eigen::VectorXd& b,
                                 Eigen::VectorXd& x, double budget_ms, FrameStats& st,
                                 std::span<const Eigen::VectorXd> prediction) {
  if (st.products == 0 && st.solve_ms == 0) st.setup_ms = ms_since(frame_start_);
  if (opt_.backend == StiffnessBackend::Petsc) {
    solve_petsc(k, a, c, b, x, st);
    return;
  }
  if (opt_.method == SolverMethod::Direct) {
    const auto t0 = std::chrono::steady_clock::now();
    if (direct_dirty_ || model_.kind() == FemKind::Corotational || a != direct_mass_coeff_ || c != direct_stiffness_coeff_) {
      if (!direct_) direct_ = std::make_unique<DirectSolver>();
      Eigen::SparseMatrix<double> mat = c * model_.assemble();
      if (a != 0) {
        const Eigen::VectorXd& m = model_.lumped_mass();
        for (Eigen::Index i = 0; i < mat.outerSize(); ++i) mat.coeffRef(i, i) += a * m[i];
      }
      direct_->compute(mat, free_);
      direct_dirty_ = false;
      direct_mass_coeff_ = a;
      direct_stiffness_coeff_ = c;
    }
    // Report the true residual so CG and direct stats compare.
    ScaledSystem op(k, model_.lumped_mass(), a, c);
    const Eigen::VectorXd bk = lifted_rhs(op, b, x, free_);
    direct_->solve(b, x);
    st.relative_residual = free_relative_residual(op, b, x, free_, bk);
    st.solve_ms += ms_since(t0);
    check_finite(x, st);
    return;
  }
  if (system_dirty_ || &k != system_k_ || a != system_a_ || c != system_c_) {
    system_ = std::make_unique<ScaledSystem>(k, model_.lumped_mass(), a, c);
    system_k_ = &k;
    system_a_ = a;
    system_c_ = c;
    system_dirty_ = false;
    cg_.compute(*system_, &free_);
  }
  cg_.set_budget_ms(budget_ms);
  const bool first = st.iterations == 0 && !st.resumed && st.initial_relative_residual == 0;
  cg_.solve_with_guess(b, x, prediction);
  const SolveStats& s = cg_.stats();
  if (first) {
    st.initial_relative_residual = s.initial_relative_residual;
    st.guess_relative_residual = s.guess_relative_residual;
    st.resumed = s.resumed;
  }
  st.iterations += s.iterations;
  st.products += s.products;
  st.relative_residual = s.relative_residual;
  st.solve_ms += s.solve_ms;
  st.preconditioner_setup_ms += s.preconditioner_setup_ms;
  st.budget_exhausted = st.budget_exhausted || s.budget_exhausted;
  st.cheaper_preconditioner = st.cheaper_preconditioner || s.cheaper_preconditioner;
  st.info = s.info;
  st.message = s.message;
  check_finite(x, st);
}

// PETSc assembles a M + c K from the model's elements (again after a topology change, a new
// constraint or, corotational, every relinearization: re-assembly is its local update) and
// solves the free block; the held values enter through the lifted right-hand side.
void FemSimulation::solve_petsc(const LinearOperator& k, double a, double c, const Eigen::VectorXd& b,
                                Eigen::VectorXd& x, FrameStats& st) {
  // Made outside the timing: the first one starts PETSc (and MPI), a process's start-up.
  if (!petsc_) petsc_ = std::make_unique<PetscSolver>(opt_.petsc_options, opt_.cg.tolerance, opt_.cg.max_iterations);
  const auto t0 = std::chrono::steady_clock::now();
  if (direct_dirty_ || model_.kind() == FemKind::Corotational || a != direct_mass_coeff_ || c != direct_stiffness_coeff_) {
    petsc_->compute(model_, a, c, free_);
    direct_dirty_ = false;
    direct_mass_coeff_ = a;
    direct_stiffness_coeff_ = c;
    st.preconditioner_setup_ms += ms_since(t0);
  }
  ScaledSystem op(k, model_.lumped_mass(), a, c);
  const Eigen::VectorXd bk = lifted_rhs(op, b, x, free_);
  const PetscSolveStats ps = petsc_->solve(bk, x);
  st.relative_residual = free_relative_residual(op, b, x, free_, bk);
  st.iterations += ps.iterations;
  st.products += ps.iterations;
  st.solve_ms += ms_since(t0);
  st.info = ps.converged ? SolveInfo::Success : SolveInfo::NoConvergence;
  if (!ps.converged) st.message = "petsc: " + ps.reason;
  check_finite(x, st);
}

// A solution or residual that is not finite is a breakdown whatever the solver concluded: the
// direct solver has no verdict of its own, and a residual whose norm overflows vouches for
// nothing. One pass over x, cheaper than any solve.
void FemSimulation::check_finite(const Eigen::VectorXd& x, FrameStats& st) const {
  if (st.info == SolveInfo::NotPositiveDefinite || st.info == SolveInfo::NumericalIssue) return;
  const bool x_ok = x.allFinite();
  if (x_ok && std::isfinite(st.relative_residual)) return;
  st.info = SolveInfo::NumericalIssue;
  st.message = std::string(opt_.backend == StiffnessBackend::Petsc ? "petsc"
                           : opt_.method == SolverMethod::Direct ? "direct solver"
                                                                 : "cg") +
               (x_ok ? ": the residual is not finite (loads or displacements beyond double precision?)"
                     : ": NaN/Inf in the solution");
}

void FemSimulation::relinearize() {
  if (model_.kind() != FemKind::Corotational) return;
  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t packets = model_.rotation_packets();
  std::size_t count = packets;
  // A budget that cannot afford every tet's rotation gets the share it can; the cursor takes
  // the rest in turn over the next frames (measured cost per packet: the first refresh is whole).
  if (frame_budget_ms_ > 0 && relinearize_ms_per_packet_ > 0 && packets > 0)
    count = std::clamp(std::size_t(opt_.relinearize_share * frame_budget_ms_ / relinearize_ms_per_packet_),
                       std::size_t(1), packets);
  if (count >= packets) {
    model_.update_rotations(u_);
  } else {
    model_.update_rotations_partial(u_, relinearize_cursor_, count);
    relinearize_cursor_ = (relinearize_cursor_ + count) % packets;
  }
  // The cost per packet is learnt from refreshes of at least kMeasuredPackets: a frame whose
  // budget a cut had used up refreshes one packet, and its fixed cost (the parallel loop's
  // start) counted as one packet's made the next frames refresh a tenth of what they could.
  constexpr std::size_t kMeasuredPackets = 32;
  if (packets > 0 && (count >= packets || count >= kMeasuredPackets || relinearize_ms_per_packet_ <= 0)) {
    const double per = ms_since(t0) / double(count);
    relinearize_ms_per_packet_ = relinearize_ms_per_packet_ > 0 ? 0.7 * relinearize_ms_per_packet_ + 0.3 * per : per;
  }
  if (packets > 0) stats_.relinearized = std::min(stats_.relinearized, double(count) / double(packets));
  b_rot_.setZero(model_.rows());
  model_.add_rotation_rhs(b_rot_);
  assembled_dirty_ = system_dirty_ = true;
}

// b_ = external + body (+ corotational term), x_ = u_ with the prescribed values on kept unknowns.
void FemSimulation::static_rhs_and_guess() {
  body_and_external_forces(b_);
  if (model_.kind() == FemKind::Corotational) b_ += b_rot_;
  x_ = opt_.warm_start ? u_ : Eigen::VectorXd::Zero(u_.size());
  for (std::size_t i = 0; i < free_.size(); ++i)
    if (!free_[i]) x_[Eigen::Index(i)] = target_[Eigen::Index(i)];
}

const FrameStats& FemSimulation::step(double spent_ms) {
  const auto t0 = frame_start_ = std::chrono::steady_clock::now();
  // What the caller already spent on this frame (a cut step and its updates) comes off the
  // budget, so that budget_ms bounds the whole frame, not only the solve.
  spent_ms = std::max(0.0, spent_ms);
  frame_budget_ms_ = opt_.cg.budget_ms > 0 ? std::max(1e-6, opt_.cg.budget_ms - spent_ms) : 0.0;
  // Iterations on the cheaper preconditioner say nothing of the factor's staleness: a budget
  // that cannot afford the factor must not keep a core busy refreshing it.
  const int last_iterations = stats_.cheaper_preconditioner ? 0 : stats_.iterations;
  stats_ = FrameStats{};
  stats_.outside_ms = spent_ms;
  grow();
  // Under-constrained static problems are refused before anything else, so no factorization of
  // a singular matrix is started for them.
  if (!opt_.dynamic && opt_.check_rigid_modes && rigid_dirty_) {
    check_rigid_modes();
    rigid_dirty_ = false;
  }
  if (quadratic_) {
    step_quadratic();
    stats_.frame_ms = ms_since(t0);
    changed_since_frame_ = false;
    return stats_;
  }
  if (mixed_) {
    step_mixed(t0);
    stats_.frame_ms = ms_since(t0);
    changed_since_frame_ = false;
    return stats_;
  }
  // The asynchronous factor: adopt a finished one, start a fresh one if due, before anything
  // below decides whether CG resumes (a new factor means a restart).
  if (uses_own_cg() && cg_.options().preconditioner == Preconditioner::Cholesky) {
    if (!cholesky_) {
      // A budgeted frame never waits for the first factor: block-Jacobi until it lands.
      AsyncCholeskyOptions co = opt_.cholesky;
      if (opt_.cg.budget_ms > 0) co.wait_for_first = false;
      cholesky_ = std::make_unique<AsyncCholesky>(model_, co);
      cg_.set_preconditioner(cholesky_.get());
      if (co.settle_with_amg) {
        amg_ = std::make_unique<AggregationAmg>(model_, opt_.amg);
        cholesky_->set_moving(amg_.get());
      }
    }
    if (amg_) {
      if (opt_.dynamic) amg_->frame(1 + opt_.dt * opt_.damping, opt_.dt * opt_.dt, last_iterations);
      else amg_->frame(0.0, 1.0, last_iterations);
    }
    if (opt_.dynamic) cholesky_->frame(free_, 1 + opt_.dt * opt_.damping, opt_.dt * opt_.dt, last_iterations);
    else cholesky_->frame(free_, 0.0, 1.0, last_iterations);
  } else if (cholesky_) {
    cg_.set_preconditioner(nullptr);
    cholesky_.reset();
    amg_.reset();  // it was the factor's (settle_with_amg)
  }
  if (uses_own_cg() && cg_.options().preconditioner == Preconditioner::Amg) {
    if (!amg_) {
      amg_ = std::make_unique<AggregationAmg>(model_, opt_.amg);
      cg_.set_preconditioner(amg_.get());
    }
    if (opt_.dynamic) amg_->frame(1 + opt_.dt * opt_.damping, opt_.dt * opt_.dt, last_iterations);
    else amg_->frame(0.0, 1.0, last_iterations);
  } else if (amg_ && !cholesky_) {
    cg_.set_preconditioner(nullptr);
    amg_.reset();
  }
  const LinearOperator* k = &model_;
  auto refresh_operator = [&] {
    if (opt_.backend == StiffnessBackend::Assembled && opt_.method == SolverMethod::Cg) {
      if (!assembled_) {
        assembled_ = std::make_unique<AssembledStiffness>(model_);
        system_dirty_ = true;
      } else if (assembled_dirty_) {
        assembled_->rebuild();
        system_dirty_ = true;
      }
      assembled_dirty_ = false;
      k = assembled_.get();
    }
  };
  const double budget = frame_budget_ms_;
  auto remaining = [&] {
    if (budget <= 0) return 0.0;
    return std::max(1e-6, budget - ms_since(t0));
  };
  auto resumable = [&] { return uses_own_cg() && !system_dirty_ && cg_.can_resume(b_, x_); };

  if (!opt_.dynamic) {
    const bool corot = model_.kind() == FemKind::Corotational;
    const int rounds = corot ? opt_.nonlinear_iterations : 1;
    for (int it = 0; it < rounds; ++it) {
      // A solve the budget interrupted continues on its own linearization when nothing else
      // changed: new rotations would change the operator and force a restart every frame.
      bool fresh_rotations = corot;
      if (corot && it == 0 && b_rot_.size() == model_.rows()) {
        static_rhs_and_guess();
        fresh_rotations = !resumable();
      }
      if (fresh_rotations) relinearize();
      refresh_operator();
      static_rhs_and_guess();
      std::span<const Eigen::VectorXd> prediction;
      // Not in a frame right after a topology change: the history at the new vertices is
      // interpolated from their parents and knows nothing of the opening, and extrapolating
      // it cost CG iterations (organ cut scene: 24 / 43 median / max a frame against 21 / 40
      // from the last solution, four products more; docs/solver.md).
      if (opt_.warm_start && opt_.predict && it == 0 && uses_own_cg() && !resumable() &&
          !changed_since_frame_) {
        // directions() fills (and may reallocate) d_: take its data after the call, not in the
        // same argument list (the order arguments are evaluated in is unspecified; clang took
        // data() first and handed CG a null or stale pointer).
        const auto n = std::size_t(predictor_.directions(free_, d_));
        prediction = std::span<const Eigen::VectorXd>(d_.data(), n);
      }
      solve_system(*k, 0.0, 1.0, b_, x_, remaining(), stats_, prediction);
      if (stats_.info == SolveInfo::NotPositiveDefinite || stats_.info == SolveInfo::NumericalIssue) break;
      u_ = x_;
      if (stats_.budget_exhausted) break;
    }
    // Unconverged frames are recorded too: the initial-residual line search in CG discards a
    // prediction that would start worse than the last solution.
    if (stats_.info == SolveInfo::NotPositiveDefinite || stats_.info == SolveInfo::NumericalIssue) predictor_.clear();
    else predictor_.record(u_);
  } else {
    const double dt = opt_.dt;
    relinearize();
    refresh_operator();
    // b = M v + dt (f_ext + f_int(u))
    body_and_external_forces(b_);
    model_.internal_forces(u_, tmp_);
    b_ = model_.lumped_mass().cwiseProduct(v_) + dt * (b_ + tmp_);
    x_ = opt_.warm_start ? v_ : Eigen::VectorXd::Zero(v_.size());
    for (std::size_t i = 0; i < free_.size(); ++i)
      if (!free_[i]) x_[Eigen::Index(i)] = (target_[Eigen::Index(i)] - u_[Eigen::Index(i)]) / dt;
    solve_system(*k, 1 + dt * opt_.damping, dt * dt, b_, x_, remaining(), stats_, {});
    if (stats_.info != SolveInfo::NotPositiveDefinite && stats_.info != SolveInfo::NumericalIssue) {
      v_ = x_;
      u_ += dt * v_;
    }
  }
  stats_.frame_ms = ms_since(t0);
  changed_since_frame_ = false;
  return stats_;
}

// The mixed formulation's frame: the same loads, constraints and integrator, solved for
// displacement and pressure by the MixedSolver (which keeps the pressure and an interrupted
// MINRES between frames).
void FemSimulation::step_mixed(std::chrono::steady_clock::time_point t0) {
  MixedSolver& ms = *mixed_;
  const double budget = frame_budget_ms_;
  auto remaining = [&] { return budget <= 0 ? 0.0 : std::max(1e-6, budget - ms_since(t0)); };
  auto record = [&](const MixedStats& m) {
    stats_.iterations += m.iterations;
    stats_.products += m.iterations;
    stats_.relative_residual = m.relative_residual;
    if (stats_.products == m.iterations) stats_.initial_relative_residual = m.initial_relative_residual;
    stats_.resumed = stats_.resumed || m.resumed;
    stats_.solve_ms += m.solve_ms;
    stats_.preconditioner_setup_ms += m.setup_ms;
    stats_.budget_exhausted = m.budget_exhausted;
    mixed_pending_ = m.budget_exhausted;
    if (m.budget_exhausted) {
      stats_.info = SolveInfo::BudgetExhausted;
    } else if (m.breakdown) {
      stats_.info = SolveInfo::NumericalIssue;
      stats_.message = "mixed solver: breakdown (NaN/Inf, or a singular system: is the pressure free to float?)";
    } else if (!m.converged && !m.budget_exhausted) {
      stats_.info = SolveInfo::NoConvergence;
      stats_.message = "mixed solver: not converged within the iteration cap";
    }
  };
  const bool corot = opt_.kind == FemKind::Corotational;
  stats_.setup_ms = ms_since(t0);
  if (!opt_.dynamic) {
    if (ms.mass_coeff() != 0 || ms.stiffness_coeff() != 1) ms.set_system(0, 1);
    const int rounds = corot ? opt_.nonlinear_iterations : 1;
    for (int it = 0; it < rounds; ++it) {
      // An interrupted solve continues on its own linearization (new rotations would restart it).
      if (corot && !(it == 0 && mixed_pending_)) ms.update_rotations(u_);
      body_and_external_forces(b_);
      x_ = opt_.warm_start ? u_ : Eigen::VectorXd::Zero(u_.size());
      for (std::size_t i = 0; i < free_.size(); ++i)
        if (!free_[i]) x_[Eigen::Index(i)] = target_[Eigen::Index(i)];
      ms.set_budget_ms(remaining());
      record(ms.solve(b_, free_, x_));
      if (stats_.info == SolveInfo::NumericalIssue) break;
      u_ = x_.head(u_.size());
      if (stats_.budget_exhausted) break;
    }
    check_finite(u_, stats_);
    return;
  }
  // Backward Euler (see MixedSolver::set_system): unknowns v' and q = p'/dt.
  const double dt = opt_.dt;
  ms.set_system(1 + dt * opt_.damping, dt * dt);
  if (corot) ms.update_rotations(u_);
  const Eigen::Index nu = Eigen::Index(ms.num_dofs()), np = Eigen::Index(ms.vertex_slots());
  body_and_external_forces(b_);
  b_.conservativeResize(nu);
  Eigen::VectorXd full_u = Eigen::VectorXd::Zero(nu + np), ku, r0 = ms.right_hand_side(Eigen::VectorXd::Zero(nu));
  full_u.head(std::min(nu, u_.size())) = u_.head(std::min(nu, u_.size()));
  ms.multiply_static(full_u, ku);  // [K_mu u; -B u]
  Eigen::VectorXd b(nu + np);
  b.head(nu) = model_.lumped_mass().head(nu).cwiseProduct(v_.head(nu)) + dt * (b_ + r0.head(nu) - ku.head(nu));
  b.tail(np) = dt * (r0.tail(np) - ku.tail(np));
  Eigen::VectorXd x(nu + np);
  x.head(nu) = opt_.warm_start ? Eigen::VectorXd(v_.head(nu)) : Eigen::VectorXd::Zero(nu);
  for (std::size_t i = 0; i < free_.size() && Eigen::Index(i) < nu; ++i)
    if (!free_[i]) x[Eigen::Index(i)] = (target_[Eigen::Index(i)] - u_[Eigen::Index(i)]) / dt;
  x.tail(np) = ms.pressure() / dt;
  ms.set_budget_ms(remaining());
  record(ms.solve_system(b, free_, x));
  if (stats_.info != SolveInfo::NumericalIssue && x.allFinite()) {
    v_.head(nu) = x.head(nu);
    u_ += dt * v_;
    ms.set_pressure(dt * x.tail(np));
  }
  check_finite(u_, stats_);
}

}  // namespace incise
