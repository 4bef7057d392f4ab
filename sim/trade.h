#pragma once
// incise trade: plays one scene under a grid of solver settings and measures, for each, the
// time per frame and the error against a reference, so a user can pick settings for a scene.
//
// Reference: the scene's mesh, loads and materials with static corotational FEM solved by the
// direct solver, re-linearized solver.nonlinear_iterations times per frame like the runs, so
// the error measures what the model and solver choices change. Error of a
// run: the largest over frames of ||u_f - u_ref,f|| / ||u_ref,f|| (nodal displacements, 2-norm
// over all vertices; a frame with ||u_ref,f|| = 0 compares absolute values). Time per frame:
// the mean wall time of a frame's step (setup, rotations, right-hand side, solve; a background
// factorization runs on another thread and is not counted).
#include <functional>
#include <iosfwd>
#include <string>
#include <vector>

#include "sim/scene.h"

namespace incise {

struct TradeOptions {
  std::vector<SceneModel> models{SceneModel::FemLinear, SceneModel::FemCorotational, SceneModel::Springs};  // all three
  std::vector<Preconditioner> preconditioners{Preconditioner::Jacobi, Preconditioner::BlockJacobi,
                                              Preconditioner::Cholesky};  // CG runs
  std::vector<double> tolerances{1e-2, 1e-4, 1e-6, 1e-8};  // CG relative residual targets
  std::vector<double> budgets_ms{0, 2};                    // per-frame CG budgets; 0 = none
  bool direct = true;                                      // also the direct solver per FEM model
  int frames = -1;                                         // override the scene's frames when >= 0
  std::ostream* progress = nullptr;                        // one line per run (stderr in the CLI)
};

struct TradeRow {
  std::string model, solver, preconditioner;  // solver: "cg", "direct" or the spring integrator
  double tolerance = 0, budget_ms = 0;
  double ms_per_frame = 0, iterations = 0;   // iterations: mean per frame
  double error = 0;                          // see above
  int frames_not_converged = 0;
  bool pareto = false;                       // no other row is both faster and more accurate
};

// Runs the grid (the reference first). Throws what run_scene throws, naming the setting.
std::vector<TradeRow> run_trade(const Scene& scene, const TradeOptions& options);

// Marks the Pareto frontier of (ms_per_frame, error).
void mark_pareto(std::vector<TradeRow>& rows);

// CSV with a header: model,solver,preconditioner,tolerance,budget_ms,ms_per_frame,iterations,
// error,frames_not_converged,pareto.
std::string trade_csv(const std::vector<TradeRow>& rows);
// Error against time per frame (log-log), one colour per model, the Pareto frontier drawn.
std::string trade_svg(const std::vector<TradeRow>& rows, const std::string& title);

}  // namespace incise
