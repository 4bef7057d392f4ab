#include "sim/trade.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "mesh/errors.h"

namespace incise {

namespace {

const char* model_name(SceneModel m) {
  switch (m) {
    case SceneModel::FemLinear: return "fem-linear";
    case SceneModel::FemCorotational: return "fem-corotational";
    case SceneModel::Springs: return "springs";
  }
  return "?";
}

struct Setting {
  Scene scene;
  TradeRow row;
};

// The settings of the grid, in the order they run.
std::vector<Setting> grid(const Scene& base, const TradeOptions& opt) {
  std::vector<Setting> out;
  for (SceneModel model : opt.models) {
    Scene s = base;
    s.model = model;
    TradeRow r;
    r.model = model_name(model);
    if (model == SceneModel::Springs) {
      // Springs are dynamic: implicit Euler at the scene's time step, its CG at each tolerance.
      s.integrator = "implicit-euler";
      s.method = SolverMethod::Cg;
      for (double tol : opt.tolerances) {
        Setting st{s, r};
        st.scene.cg.tolerance = tol;
        st.row.solver = "implicit-euler";
        st.row.tolerance = tol;
        out.push_back(st);
      }
      continue;
    }
    if (s.integrator != "static" && s.integrator != "implicit-euler") s.integrator = "static";
    if (opt.direct) {
      Setting st{s, r};
      st.scene.method = SolverMethod::Direct;
      st.row.solver = "direct";
      out.push_back(st);
    }
    for (Preconditioner pc : opt.preconditioners)
      for (double tol : opt.tolerances)
        for (double budget : opt.budgets_ms) {
          Setting st{s, r};
          st.scene.method = SolverMethod::Cg;
          st.scene.cg.preconditioner = pc;
          st.scene.cg.tolerance = tol;
          st.scene.cg.budget_ms = budget;
          st.scene.cg.max_iterations = std::max(st.scene.cg.max_iterations, 20000);
          st.row.solver = "cg";
          st.row.preconditioner = to_string(pc);
          st.row.tolerance = tol;
          st.row.budget_ms = budget;
          out.push_back(st);
        }
  }
  return out;
}

std::string fmt(double v) {
  std::ostringstream s;
  s << std::setprecision(6) << v;
  return s.str();
}

}  // namespace

std::vector<TradeRow> run_trade(const Scene& scene, const TradeOptions& opt) {
  // Reference: static corotational FEM, direct, re-linearized per frame.
  Scene ref_scene = scene;
  ref_scene.model = SceneModel::FemCorotational;
  ref_scene.method = SolverMethod::Direct;
  ref_scene.integrator = "static";
  std::vector<Eigen::VectorXd> ref;
  SceneRunOptions ro;
  ro.frames = opt.frames;
  ro.on_frame = [&](int, const Eigen::VectorXd& d, const FrameStats&) { ref.push_back(d); };
  const auto t0 = std::chrono::steady_clock::now();
  run_scene(ref_scene, ro);
  if (opt.progress)
    *opt.progress << "trade: reference (fem-corotational, direct, " << ref_scene.nonlinear_iterations
                  << " linearizations per frame): " << ref.size() << " frames, "
                  << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s\n";

  std::vector<Setting> settings = grid(scene, opt);
  std::vector<TradeRow> rows;
  for (std::size_t i = 0; i < settings.size(); ++i) {
    Setting& st = settings[i];
    TradeRow& r = st.row;
    double ms = 0, iterations = 0;
    int frames = 0;
    ro.on_frame = [&](int f, const Eigen::VectorXd& d, const FrameStats& s) {
      const Eigen::VectorXd& u = ref.at(std::size_t(f));
      const double n = u.norm(), e = (d - u).norm();
      r.error = std::max(r.error, n > 0 ? e / n : e);
      ms += s.frame_ms;
      iterations += s.iterations;
      r.frames_not_converged += s.info != SolveInfo::Success;
      ++frames;
    };
    try {
      run_scene(st.scene, ro);
    } catch (const Error& e) {
      throw Error(std::string("trade: ") + r.model + " " + r.solver + " " + r.preconditioner + " tolerance " +
                  fmt(r.tolerance) + " budget " + fmt(r.budget_ms) + ": " + e.what());
    }
    r.ms_per_frame = frames ? ms / frames : 0;
    r.iterations = frames ? iterations / frames : 0;
    if (opt.progress)
      *opt.progress << "trade: " << i + 1 << "/" << settings.size() << " " << r.model << " " << r.solver
                    << (r.preconditioner.empty() ? "" : " " + r.preconditioner) << " tol " << fmt(r.tolerance)
                    << " budget " << fmt(r.budget_ms) << " ms: " << fmt(r.ms_per_frame) << " ms/frame, "
                    << fmt(r.iterations) << " iterations/frame, error " << fmt(r.error) << "\n";
    rows.push_back(r);
  }
  mark_pareto(rows);
  return rows;
}

void mark_pareto(std::vector<TradeRow>& rows) {
  for (TradeRow& a : rows) {
    a.pareto = true;
    for (const TradeRow& b : rows)
      if (&a != &b && b.ms_per_frame <= a.ms_per_frame && b.error <= a.error &&
          (b.ms_per_frame < a.ms_per_frame || b.error < a.error))
        a.pareto = false;
  }
}

std::string trade_csv(const std::vector<TradeRow>& rows) {
  std::ostringstream s;
  s << "model,solver,preconditioner,tolerance,budget_ms,ms_per_frame,iterations,error,frames_not_converged,pareto\n";
  s << std::setprecision(8);
  for (const TradeRow& r : rows)
    s << r.model << "," << r.solver << "," << r.preconditioner << "," << r.tolerance << "," << r.budget_ms << ","
      << r.ms_per_frame << "," << r.iterations << "," << r.error << "," << r.frames_not_converged << ","
      << (r.pareto ? 1 : 0) << "\n";
  return s.str();
}

}  // namespace incise
