#include "sim/fem/cg_spectrum.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#include "mesh/clock.h"
#include "mesh/errors.h"

namespace incise {

namespace {

bool positive(double x) { return x > 0 && std::isfinite(x); }

}  // namespace

LanczosExtremes lanczos_extremes(const CgCoefficients& c) {
  const std::size_t k = c.alpha.size();
  LanczosExtremes out;
  if (k == 0) return out;
  if (c.beta.size() + 1 < k) throw InvalidArgument("lanczos_extremes: fewer betas than alphas - 1");
  Eigen::VectorXd diag = Eigen::VectorXd::Zero(Eigen::Index(k)), off = Eigen::VectorXd::Zero(Eigen::Index(k - 1));
  for (std::size_t j = 0; j < k; ++j) {
    if (!positive(c.alpha[j]) || (j + 1 < k && !positive(c.beta[j])))
      throw InvalidArgument("lanczos_extremes: CG coefficients must be positive and finite");
    diag[Eigen::Index(j)] = 1 / c.alpha[j] + (j > 0 ? c.beta[j - 1] / c.alpha[j - 1] : 0.0);
    if (j + 1 < k) off[Eigen::Index(j)] = std::sqrt(c.beta[j]) / c.alpha[j];
  }
  out.steps = int(k);
  if (k == 1) {
    out.ritz = {diag[0]};
  } else {
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es;
    es.computeFromTridiagonal(diag, off, Eigen::EigenvaluesOnly);
    out.ritz.assign(es.eigenvalues().data(), es.eigenvalues().data() + k);
    std::sort(out.ritz.begin(), out.ritz.end());
  }
  out.lambda_min = out.ritz.front();
  out.lambda_max = out.ritz.back();
  return out;
}

double cg_iterations_for(double kappa, double tolerance) { return 0.5 * std::sqrt(kappa) * std::log(2.0 / tolerance); }

double cg_iterations_with_outliers(const std::vector<double>& ritz, double tolerance, int max_outliers) {
  if (ritz.empty()) return 0;
  const double lo = ritz.front();
  double best = cg_iterations_for(ritz.back() / lo, tolerance), last = ritz.back();
  // The lower Ritz values stand for the bulk of the spectrum, not for single eigenvalues.
  const int cap = std::min(max_outliers, int(ritz.size()) / 10);
  int m = 0;
  for (auto it = ritz.rbegin(); it != ritz.rend() && m < cap; ++it) {
    if (!(*it < last * (1 - 1e-6))) continue;  // a repeat of the value just removed
    last = *it;
    ++m;
    best = std::min(best, m + cg_iterations_for(last / lo, tolerance));
  }
  return best;
}

ClampedProblem clamped_problem(const FemModel& model, double clamp_fraction) {
  if (!(clamp_fraction > 0 && clamp_fraction < 1)) throw InvalidArgument("clamped_problem: clamp fraction must be in (0, 1)");
  const TetMesh& mesh = model.mesh();
  ClampedProblem p;
  const std::size_t slots = model.vertex_slots();
  p.free.assign(3 * slots, 0);
  p.load.setZero(Eigen::Index(3 * slots));
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (VertexId v : mesh.vertices()) {
    if (mesh.incident_tets(v).empty()) continue;
    lo = lo.cwiseMin(mesh.rest(v));
    hi = hi.cwiseMax(mesh.rest(v));
  }
  if (!(hi.x() >= lo.x())) return p;  // no vertex in a tet
  const Vec3 ext = hi - lo;
  ext.maxCoeff(&p.clamp_axis);
  ext.minCoeff(&p.load_axis);
  if (p.load_axis == p.clamp_axis) p.load_axis = (p.clamp_axis + 1) % 3;  // a cube: any other axis
  const double cut = lo[p.clamp_axis] + clamp_fraction * ext[p.clamp_axis];
  const Eigen::VectorXd& mass = model.lumped_mass();
  for (VertexId v : mesh.vertices()) {
    if (mesh.incident_tets(v).empty()) continue;
    const std::size_t i = v.idx();
    if (mesh.rest(v)[p.clamp_axis] <= cut) {
      ++p.fixed_vertices;
      continue;
    }
    p.free[3 * i] = p.free[3 * i + 1] = p.free[3 * i + 2] = 1;
    p.load[Eigen::Index(3 * i + std::size_t(p.load_axis))] = -mass[Eigen::Index(3 * i)];
  }
  return p;
}

CgSpectrumRun run_cg_spectrum(const FemModel& model, const ClampedProblem& problem, Preconditioner pc,
                              int max_iterations, double tolerance) {
  CgOptions o;
  o.tolerance = tolerance;
  o.max_iterations = max_iterations;
  o.preconditioner = pc;
  ConjugateGradient cg(o);
  CgCoefficients log;
  cg.set_coefficient_log(&log);
  cg.compute(model, &problem.free);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(model.rows());
  cg.solve_with_guess(problem.load, x);
  CgSpectrumRun run;
  run.preconditioner = pc;
  run.iterations = cg.iterations();
  run.converged = cg.stats().converged();
  run.ms = cg.stats().solve_ms;
  if (cg.info() == SolveInfo::NotPositiveDefinite || cg.info() == SolveInfo::NumericalIssue)
    throw Error(cg.stats().message);
  run.ritz = lanczos_extremes(log);
  run.kappa = run.ritz.steps > 0 ? run.ritz.kappa() : 1.0;
  run.classic_iterations = cg_iterations_for(run.kappa, tolerance);
  run.predicted_iterations =
      run.converged ? run.iterations : cg_iterations_with_outliers(run.ritz.ritz, tolerance);
  return run;
}

MeasuredSolverEstimate measure_solver(const TetMesh& mesh, const MeasuredSolverOptions& opt) {
  if (!(opt.tolerance > 0 && opt.tolerance < 1)) throw InvalidArgument("measure_solver: tolerance must be in (0, 1)");
  if (!(opt.poisson_ratio > -1 && opt.poisson_ratio < 0.5))
    throw InvalidArgument("measure_solver: Poisson ratio must be in (-1, 0.5)");
  if (opt.lanczos_iterations < 1) throw InvalidArgument("measure_solver: lanczos iterations must be >= 1");
  const double t0 = now_ms();
  MeasuredSolverEstimate est;
  est.source = "measured: Lanczos from " + std::to_string(opt.lanczos_iterations) + " CG iterations";
  if (mesh.num_tets() == 0) {
    est.reason = "no tets";
    return est;
  }
  if (opt.poisson_ratio < 0) {
    est.reason = "the FEM model takes Poisson ratios in [0, 0.5)";
    return est;
  }
  Material m;
  m.young = 1;
  m.poisson = opt.poisson_ratio;
  try {
    const FemModel model(mesh, MaterialTable(m), FemKind::Linear);
    est.problem = clamped_problem(model, opt.clamp_fraction);
    est.model_ms = now_ms() - t0;
    if (est.problem.fixed_vertices == 0) {
      est.reason = "no vertex to clamp";
      return est;
    }
    est.none = run_cg_spectrum(model, est.problem, Preconditioner::None, opt.lanczos_iterations, opt.tolerance);
    est.jacobi = run_cg_spectrum(model, est.problem, Preconditioner::Jacobi, opt.lanczos_iterations, opt.tolerance);
  } catch (const InvalidMesh& e) {  // a degenerate tet: K is singular
    est.reason = e.what();
    return est;
  } catch (const InvalidArgument&) {
    throw;
  } catch (const Error& e) {  // the solve broke down
    est.reason = e.what();
    return est;
  }
  est.available = est.none.ritz.steps > 0 && est.jacobi.ritz.steps > 0 && std::isfinite(est.none.kappa) &&
                  std::isfinite(est.jacobi.kappa);
  if (!est.available) est.reason = "the load has no free component (nothing to solve)";
  est.total_ms = now_ms() - t0;
  return est;
}

}  // namespace incise
