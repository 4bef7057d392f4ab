// SpringModel time stepping: explicit Euler, symplectic Euler, velocity Verlet and linearized
// backward Euler with a matrix-free, Jacobi-preconditioned CG on the spring Jacobian.
#include <cmath>
#include <iostream>
#include <optional>
#include <sstream>

#include "mesh/errors.h"
#include "sim/springs/spring_model.h"

namespace incise {

void SpringModel::warn_once(Integrator integrator, double dt, double limit) {
  const unsigned bit = 1u << static_cast<unsigned>(integrator);
  if (warned_ & bit) return;
  double estimate = 0;
  if (limit > 0) {
    // The local bound is loose, well below the real limit (docs/solver.md#spring-stable-step):
    // a step above it is measured against the state's fastest mode before it is warned about,
    // once per bound (a cut moves both) unless the step grows. O(mesh), so not every step: a
    // squeeze that stiffens the state later is not seen.
    EstimateCheck& c = checked_[static_cast<std::size_t>(integrator)];
    if (c.bound != limit || dt > c.dt) {
      try {
        c.estimate = estimated_stable_time_step(integrator);
      } catch (const std::exception&) {  // a state the estimate cannot read: the bound warns
        c.estimate = 0;
      }
      c.bound = limit;
      c.dt = dt;
    }
    estimate = c.estimate;
    if (dt <= estimate) return;
  }
  warned_ |= bit;
  std::cerr << "incise: warn: " << integrator_name(integrator) << " time step " << dt;
  if (estimate > 0)
    std::cerr << " exceeds the stable step " << estimate << " estimated from the state's fastest mode (and the bound "
              << limit << ", Gershgorin at rest); the motion may blow up";
  else if (limit > 0)
    std::cerr << " exceeds the stable step's bound " << limit << " (Gershgorin at rest, w_max <= "
              << max_angular_frequency() << " rad/s); the motion may blow up";
  else
    std::cerr << " is unstable: explicit Euler without damping gains energy at any time step";
  std::cerr << " (reported once)\n";
}

// Prescribed vertices jump to their target with the velocity that gets them there; fixed
// ones stay. Called where the integrators would otherwise have moved them.
void SpringModel::finish_constraints(double dt) {
  for (std::size_t i = 0; i < x_.size(); ++i) {
    if (!active(static_cast<std::uint32_t>(i))) continue;
    if (fixed_[i]) {
      v_[i] = Vec3::Zero();
    } else if (prescribed_[i]) {
      v_[i] = (target_[i] - x_[i]) / dt;
      x_[i] = target_[i];
    }
  }
}

StepStats SpringModel::step(double dt, Integrator integrator) {
  if (!(dt > 0) || !std::isfinite(dt)) throw InvalidArgument("spring step: dt must be finite and > 0");
  StepStats st;
  st.dt = dt;
  if (is_explicit(integrator)) {
    const double limit = stable_time_step(integrator);
    if (dt > limit * (1 + 1e-12)) {
      st.stable_step_exceeded = true;
      warn_once(integrator, dt, limit);
    }
  }
  // A step that blows up (an explicit step far past the stable one, an implicit step whose
  // solve diverged) must not leave NaN behind: steps that can are taken from a copy of the
  // state (explicit ones past the limit only: the copy costs about what the step does).
  std::optional<std::pair<std::vector<Vec3>, std::vector<Vec3>>> before;
  if (st.stable_step_exceeded || integrator == Integrator::ImplicitEuler) before.emplace(x_, v_);
  const std::size_t n = x_.size();
  switch (integrator) {
    case Integrator::ExplicitEuler:
      compute_forces(x_, v_, force_);
      for (std::size_t i = 0; i < n; ++i) {
        if (!free_dof(static_cast<std::uint32_t>(i))) continue;
        x_[i] += dt * v_[i];
        v_[i] += (dt / mass_[i]) * force_[i];
      }
      finish_constraints(dt);
      acc_valid_ = false;
      break;
    case Integrator::SymplecticEuler:
      compute_forces(x_, v_, force_);
      for (std::size_t i = 0; i < n; ++i) {
        if (!free_dof(static_cast<std::uint32_t>(i))) continue;
        v_[i] += (dt / mass_[i]) * force_[i];
        x_[i] += dt * v_[i];
      }
      finish_constraints(dt);
      acc_valid_ = false;
      break;
    case Integrator::Verlet:
      // Velocity Verlet; the acceleration at the end of a step is reused at the start of the
      // next, so a step costs one force evaluation. Damping sees the half-step velocity.
      if (!acc_valid_) {
        compute_forces(x_, v_, force_);
        for (std::size_t i = 0; i < n; ++i) acc_[i] = active(static_cast<std::uint32_t>(i)) ? Vec3(force_[i] / mass_[i]) : Vec3::Zero();
      }
      for (std::size_t i = 0; i < n; ++i) {
        if (!free_dof(static_cast<std::uint32_t>(i))) continue;
        v_[i] += (0.5 * dt) * acc_[i];
        x_[i] += dt * v_[i];
      }
      finish_constraints(dt);
      compute_forces(x_, v_, force_);
      for (std::size_t i = 0; i < n; ++i) {
        if (!free_dof(static_cast<std::uint32_t>(i))) continue;
        acc_[i] = force_[i] / mass_[i];
        v_[i] += (0.5 * dt) * acc_[i];
      }
      acc_valid_ = true;
      break;
    case Integrator::ImplicitEuler:
      st.cg_iterations = implicit_step(dt, st.cg_relative_residual);
      acc_valid_ = false;
      break;
  }
  if (before) {
    bool finite = true;
    for (std::size_t i = 0; i < n && finite; ++i) finite = x_[i].allFinite() && v_[i].allFinite();
    if (!finite) {
      x_ = std::move(before->first);
      v_ = std::move(before->second);
      acc_valid_ = false;
      std::ostringstream os;
      os << "spring step: the state became non-finite (dt " << dt;
      if (const double limit = is_explicit(integrator) ? stable_time_step(integrator) : 0; limit > 0)
        os << ", " << dt / limit << " times the stable time step";
      os << "); the state before the step is kept: use a smaller dt"
         << (is_explicit(integrator) ? " or the implicit-euler integrator" : "");
      throw Error(os.str());
    }
  }
  if (opt_.compute_energy) {
    st.kinetic_energy = kinetic_energy();
    st.potential_energy = potential_energy();
  }
  return st;
}

// The tangent at the current state, as implicit_step and the stable step's estimate use it:
// K = -df/dx made positive semidefinite: a spring's transverse term k (1 - l0/l) is clamped at
// 0 when compressed (Choi & Ko 2002) and the volume terms keep only their Gauss-Newton parts
// W''(J) grad J grad J^T.
void SpringModel::linearize() {
  spring_n_.resize(springs_.size());
  spring_alpha_.resize(springs_.size());
  spring_axial_.resize(springs_.size());
  for (std::size_t s = 0; s < springs_.size(); ++s) {
    const Spring& sp = springs_[s];
    const Vec3 d = x_[sp.a] - x_[sp.b];
    const double l = d.norm();
    spring_n_[s] = l > 0 ? Vec3(d / l) : Vec3::Zero();
    // Transverse: tension / l (over k), kept >= 0 so the operator stays positive definite.
    spring_alpha_[s] = l > 0 ? std::max(0.0, spring_tension(sp, l) / (sp.k * l)) : 0.0;
    spring_axial_[s] = l > 0 ? spring_axial(sp, l) : 1.0;
  }
  volume_grad_.resize(volumes_.size());
  volume_beta_.resize(volumes_.size());
  for (std::size_t t = 0; t < volumes_.size(); ++t) {
    const Volume& vol = volumes_[t];
    volume_grad_[t] = volume_gradient_of(vol);
    const double J = (x_[vol.v[1]] - x_[vol.v[0]]).dot(volume_grad_[t][1]) / vol.rest_volume;
    volume_beta_[t] = (barrier_curvature(J, tet_part() * vol.kappa, vol.rest_volume) +
                       guard_curvature(J, vol.kappa, vol.rest_volume)) /
                      (vol.rest_volume * vol.rest_volume);
  }
}

// y = a M p + b K p + c C p (C: the springs' Kelvin-Voigt damping, viscosity x k along each),
// K as linearize() left it (and nodal_ at x_, which compute_forces or nodal_volumes fill).
void SpringModel::apply_tangent(const std::vector<Vec3>& p, std::vector<Vec3>& y, double a, double b, double c) {
  const std::size_t n = x_.size();
  y.resize(n);
  for (std::size_t i = 0; i < n; ++i) y[i] = (a * mass_[i]) * p[i];
  for (std::size_t s = 0; s < springs_.size(); ++s) {
    const Spring& sp = springs_[s];
    const Vec3& nn = spring_n_[s];
    const Vec3 d = p[sp.a] - p[sp.b];
    const double nd = nn.dot(d);
    const Vec3 ye = (b * sp.k) * (spring_axial_[s] * nd * nn + spring_alpha_[s] * (d - nd * nn)) +
                    (c * sp.tau * sp.k * nd) * nn;
    y[sp.a] += ye;
    y[sp.b] -= ye;
  }
  if (opt_.nodal_volume) {
    // Gauss-Newton on sum_a W_a(J_a): beta_a g_a g_a^T with g_a = sum_{t at a} grad V_t / 4,
    // in three passes (per tet g_t . p, per vertex its quarter sums, per tet the forces),
    // the per-tet part of a blend riding in the first and the last.
    nodal_dot_.assign(n, 0.0);
    tet_dot_.resize(volumes_.size());
    for (std::size_t t = 0; t < volumes_.size(); ++t) {
      const Volume& vol = volumes_[t];
      const auto& g = volume_grad_[t];
      double s = 0;
      for (int k = 0; k < 4; ++k) s += g[k].dot(p[vol.v[k]]);
      tet_dot_[t] = s;
      for (int k = 0; k < 4; ++k) nodal_dot_[vol.v[k]] += 0.25 * s;
    }
    for (std::size_t a = 0; a < n; ++a) nodal_dot_[a] *= b * nodal_[a].beta;
    for (std::size_t t = 0; t < volumes_.size(); ++t) {
      const Volume& vol = volumes_[t];
      const auto& g = volume_grad_[t];
      double s = b * volume_beta_[t] * tet_dot_[t];
      for (int k = 0; k < 4; ++k) s += 0.25 * nodal_dot_[vol.v[k]];
      for (int k = 0; k < 4; ++k) y[vol.v[k]] += s * g[k];
    }
    return;
  }
  for (std::size_t t = 0; t < volumes_.size(); ++t) {
    const Volume& vol = volumes_[t];
    const auto& g = volume_grad_[t];
    double s = 0;
    for (int k = 0; k < 4; ++k) s += g[k].dot(p[vol.v[k]]);
    s *= b * volume_beta_[t];
    for (int k = 0; k < 4; ++k) y[vol.v[k]] += s * g[k];
  }
}

// Linearized backward Euler (Baraff & Witkin 1998):
//   (M (1 + c dt) + dt^2 K) dv = dt (f(x_n, v_n) - dt K v_n),  v += dv,  x += dt v
// with K the positive semidefinite tangent of linearize(), so the matrix is SPD on the free
// dofs and CG applies.
int SpringModel::implicit_step(double dt, double& relative_residual) {
  const std::size_t n = x_.size();
  const double dt2 = dt * dt, mc = 1 + opt_.damping * dt;
  compute_forces(x_, v_, force_);
  linearize();  // nodal_ is at x_: compute_forces filled it

  // Right-hand side and the known dv of constrained vertices.
  std::vector<Vec3>& rhs = z_;
  apply_tangent(v_, rhs, 0.0, 1.0, 0.0);  // K v
  dv_.assign(n, Vec3::Zero());
  for (std::size_t i = 0; i < n; ++i) {
    const auto u = static_cast<std::uint32_t>(i);
    rhs[i] = dt * (force_[i] - dt * rhs[i]);
    if (!active(u)) continue;
    if (fixed_[i]) dv_[i] = -v_[i];
    else if (prescribed_[i]) dv_[i] = (target_[i] - x_[i]) / dt - v_[i];
  }
  double bnorm2 = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (free_dof(static_cast<std::uint32_t>(i))) bnorm2 += rhs[i].squaredNorm();
  // r = b - A dv0 on the free dofs
  apply_tangent(dv_, r_, mc, dt2, dt);
  for (std::size_t i = 0; i < n; ++i) r_[i] = free_dof(static_cast<std::uint32_t>(i)) ? Vec3(rhs[i] - r_[i]) : Vec3::Zero();

  // Jacobi preconditioner: the diagonal of A.
  diag_.assign(n, Vec3::Zero());
  for (std::size_t i = 0; i < n; ++i) diag_[i] = Vec3::Constant(mc * mass_[i]);
  for (std::size_t s = 0; s < springs_.size(); ++s) {
    const Spring& sp = springs_[s];
    const Vec3 n2 = spring_n_[s].cwiseAbs2();
    const Vec3 dd = (dt2 * sp.k) * (spring_axial_[s] * n2 + spring_alpha_[s] * (Vec3::Ones() - n2)) +
                    (dt * sp.tau * sp.k) * n2;
    diag_[sp.a] += dd;
    diag_[sp.b] += dd;
  }
  for (std::size_t t = 0; t < volumes_.size(); ++t) {
    // Nodal: the cross terms between a vertex's tets left out, a Jacobi estimate.
    double beta = volume_beta_[t];
    if (opt_.nodal_volume)
      for (int k = 0; k < 4; ++k) beta += nodal_[volumes_[t].v[k]].beta / 16;
    for (int k = 0; k < 4; ++k) diag_[volumes_[t].v[k]] += (dt2 * beta) * volume_grad_[t][k].cwiseAbs2();
  }

  const double bnorm = std::sqrt(bnorm2);
  int it = 0;
  relative_residual = 0;
  if (bnorm > 0) {
    p_.assign(n, Vec3::Zero());
    double rz = 0, rr = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (!free_dof(static_cast<std::uint32_t>(i))) continue;
      p_[i] = r_[i].cwiseQuotient(diag_[i]);
      rz += r_[i].dot(p_[i]);
      rr += r_[i].squaredNorm();
    }
    const double tol = opt_.cg_tolerance * bnorm;
    while (std::sqrt(rr) > tol && it < opt_.cg_max_iterations) {
      apply_tangent(p_, ap_, mc, dt2, dt);
      double pap = 0;
      for (std::size_t i = 0; i < n; ++i)
        if (free_dof(static_cast<std::uint32_t>(i))) pap += p_[i].dot(ap_[i]);
      if (!(pap > 0) || !std::isfinite(pap))
        throw Error("implicit Euler: CG breakdown (p.Ap = " + std::to_string(pap) +
                    "); the state is not finite or the system is not positive definite");
      const double alpha = rz / pap;
      double rz_new = 0;
      rr = 0;
      for (std::size_t i = 0; i < n; ++i) {
        if (!free_dof(static_cast<std::uint32_t>(i))) continue;
        dv_[i] += alpha * p_[i];
        r_[i] -= alpha * ap_[i];
        rr += r_[i].squaredNorm();
      }
      ++it;
      if (std::sqrt(rr) <= tol) break;
      for (std::size_t i = 0; i < n; ++i) {
        if (!free_dof(static_cast<std::uint32_t>(i))) continue;
        rz_new += r_[i].dot(r_[i].cwiseQuotient(diag_[i]));
      }
      const double beta = rz_new / rz;
      rz = rz_new;
      for (std::size_t i = 0; i < n; ++i) {
        if (!free_dof(static_cast<std::uint32_t>(i))) continue;
        p_[i] = r_[i].cwiseQuotient(diag_[i]) + beta * p_[i];
      }
    }
    relative_residual = std::sqrt(rr) / bnorm;
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!free_dof(static_cast<std::uint32_t>(i))) continue;
    v_[i] += dv_[i];
    x_[i] += dt * v_[i];
  }
  finish_constraints(dt);
  return it;
}

}  // namespace incise
