#pragma once
// incise trade: plays one scene under a grid of settings and measures, for each, the time per
// frame and the error against a converged reference, so a user can pick settings for a scene.
//
// Reference: the scene's body refined uniformly (1:8 per level, mesh/refine.h) one level
// beyond the finest run, solved directly with static corotational quadratic tets (10 nodes;
// Taylor-Hood, P2 displacement and P1 pressure, when a material's Poisson's ratio is above
// 0.45), re-linearized solver.nonlinear_iterations times per frame like the runs. Its own error
// bar comes from Richardson extrapolation over two levels: `change` is the difference between it
// and the same reference one level coarser, and the bar change / (2^order - 1). Rows whose error
// is below the bar are marked not resolved and kept off the Pareto frontier.
//
// The convergence study (run_convergence, `incise trade --convergence`): per formulation, the
// error at each level against the same reference, and the observed order between levels.
//
// Runs are compared at shared material points: each run's vertices, located in the reference
// mesh and read there by barycentric interpolation (mesh/point_locator.h). Error of a run: the
// relative L2 of displacement over those points, ||u - u_ref|| / ||u_ref||, and the relative
// error of the largest displacement; static runs take the largest over frames. Dynamic runs
// (springs, implicit-Euler FEM) are compared at rest: played, with the loads held at their final
// values, until they settle, then compared with the reference's last frame ("at-rest"); time to
// settle and time per frame are reported. They settle with a time step of at least 1/omega,
// omega the slowest mode's frequency estimated from the reference (a Rayleigh quotient): at the
// scene's own step a soft body rings for thousands of frames before it comes to rest. Time per frame: the mean wall time of a frame's step
// (a background factorization runs on another thread and is not counted).
//
// The grid has two parts, so that it stays bounded: discretization rows (each resolution x
// model x formulation, with the scene's own solver settings) and solver rows (at the scene's
// resolution and formulation, per FEM model: the direct solver and CG per preconditioner x
// tolerance x budget).
#include <functional>
#include <iosfwd>
#include <string>
#include <vector>

#include "sim/fem/formulation.h"
#include "scene/run_scene.h"

namespace incise {

struct TradeOptions {
  std::vector<SceneModel> models{SceneModel::FemLinear, SceneModel::FemCorotational, SceneModel::Springs};
  std::vector<Formulation> formulations{Formulation::Standard, Formulation::NodalAveraged, Formulation::Mixed};
  // Springs: one row per volume term ("tet", "nodal", "none": the scene key springs.volume),
  // shown in the formulation column as "volume tet" etc.
  std::vector<std::string> spring_volumes{"tet", "nodal"};
  // And one per stiffness rule ("van-gelder", "fitted": springs.stiffness), "volume tet (fitted)".
  std::vector<std::string> spring_stiffness{"van-gelder", "fitted"};
  // And one per connectivity ("edges", "across-faces": springs.connectivity), "volume tet
  // across-faces"; springs across faces take the van-gelder constants only.
  std::vector<std::string> spring_connectivity{"edges", "across-faces"};
  // And, for the nodal volume term, one per share of it at the vertices (springs.nodal_share),
  // "volume nodal 0.75"; empty: the scene's share, one row named "volume nodal".
  std::vector<double> spring_nodal_shares;
  // Mesh levels: 0 the scene's mesh, k > 0 refined k times, -1 one coarser: a generated mesh
  // with half the cells, a mesh file coarsened to about twice its edge length
  // (quality/coarsen.h: 1/4 .. 1/8 of the tets, same labels and tags, the surface within a
  // tenth of the new edge length). Empty: -1, 0, and 1 when the reference two levels up has at
  // most max_reference_tets tets.
  std::vector<int> resolutions;
  std::size_t max_reference_tets = 50000;  // what a quadratic reference costs a tet: docs/solver.md
  // The reference is solved directly up to this many tets, by MINRES to 1e-10 above (see trade.cpp).
  std::size_t direct_reference_tets = 20000;
  int reference_level = -1;  // -1: one above the finest resolution
  std::vector<Preconditioner> preconditioners{Preconditioner::Jacobi, Preconditioner::BlockJacobi,
                                              Preconditioner::Cholesky, Preconditioner::Amg};
  std::vector<double> tolerances{1e-2, 1e-4, 1e-6, 1e-8};  // CG relative residual targets
  std::vector<double> budgets_ms{0, 2};                    // per-frame CG budgets; 0 = none
  bool direct = true;                                      // also the direct solver per FEM model
  int frames = -1;                                         // override the scene's frames when >= 0
  // Dynamic runs: settled when no vertex moved more than settle_tolerance x the largest
  // displacement in each of 3 frames in a row (after the loads' last ramp frame), or after
  // max_settle_frames.
  double settle_tolerance = 1e-4;
  int max_settle_frames = 2000;
  std::vector<double> frame_budgets_ms{2, 16, 33};  // one recommendation per frame budget
  std::ostream* progress = nullptr;                 // the plan, then one line per run (stderr in the CLI)
  // Spread over processes (`mpirun -np N incise trade`): this process plays the grid's runs i
  // with i % ranks == rank, and `gather` hands rank 0 every rank's serialized rows (rank order;
  // empty on the others), which it puts back in the grid's order: the same table as one process.
  // Every rank solves the reference itself. Other ranks return no rows.
  int rank = 0, ranks = 1;
  std::function<std::vector<std::string>(const std::string&)> gather;
};

struct TradeRow {
  int resolution = 0;                         // mesh level (see TradeOptions::resolutions)
  std::size_t tets = 0;
  std::string model, formulation, solver, preconditioner;  // solver: "cg", "direct" or "implicit-euler"
  double tolerance = 0, budget_ms = 0;
  double ms_per_frame = 0, iterations = 0;    // iterations: mean per frame
  double error = 0;                           // relative L2 of displacement (see above)
  double max_displacement_error = 0;          // relative error of the largest displacement
  std::string compared = "per-frame";         // or "at-rest" (dynamic runs)
  int settle_frames = 0;                      // at-rest: frames played until settled (0: per-frame)
  double settle_ms = 0;                       // at-rest: wall time of those frames
  double dt = 0;                              // at-rest: the time step it settled with (see run_trade)
  bool settled = true;                        // at-rest: false when max_settle_frames ran out
  int frames_not_converged = 0;
  bool pareto = false;                        // no other resolved row is both faster and more accurate
  bool resolved = true;                       // error at or above the reference's error bar
};

struct TradeReference {
  int level = 0;
  std::size_t tets = 0;
  std::string formulation;
  std::string method;  // "direct" or "minres 1e-10"
  double seconds = 0;
  // Relative L2 difference, at the scene mesh's vertices, between this reference and the same
  // solve one level coarser (-1 when level 0 has no coarser).
  double change = -1;
  // Richardson's estimate of the reference's own error: change / (2^order - 1) with the order
  // assumed for quadratic tets' displacement (docs/solver.md#quadratic-tets); -1 without change.
  double error_bar = -1;
  double order = 2;
};

struct TradeResult {
  TradeReference reference;
  std::string coarser;  // how level -1 was made (empty when it was not run)
  std::vector<TradeRow> rows;
};

// Runs the reference and the grid. Throws what run_scene throws, naming the setting.
TradeResult run_trade(const Scene& scene, const TradeOptions& options);

// Marks rows whose error is below `resolved` (the reference's error bar) not resolved, and the
// Pareto frontier of (ms_per_frame, error) among the others: an error the reference cannot
// resolve is no measured accuracy, so such rows are kept off the frontier.
void mark_pareto(std::vector<TradeRow>& rows, double resolved = 0);

// The most accurate row whose time per frame fits each budget (nullptr: none fits), errors
// below `resolved` counting as equal (then the fastest).
std::vector<const TradeRow*> recommend(const std::vector<TradeRow>& rows, const std::vector<double>& budgets_ms,
                                       double resolved = 0);

// CSV with a header: resolution,tets,model,formulation,solver,preconditioner,tolerance,budget_ms,
// ms_per_frame,iterations,error,max_displacement_error,compared,settle_frames,settle_ms,dt,settled,
// frames_not_converged,pareto,resolved.
std::string trade_csv(const std::vector<TradeRow>& rows);
// The same as JSON, with the reference and the recommendations.
std::string trade_json(const TradeResult& result, const std::vector<double>& budgets_ms);
// The frontier as a short table and one recommendation line per frame budget (stdout).
std::string trade_summary(const TradeResult& result, const std::vector<double>& budgets_ms);
// Error against time per frame (log-log): colour per model and formulation, marker per
// resolution, the Pareto frontier drawn, the frame budgets as vertical lines.
// Errors below `resolved` (> 0) lie in a shaded band: the reference does not resolve them.
std::string trade_svg(const std::vector<TradeRow>& rows, const std::string& title, const std::vector<double>& budgets_ms = {},
                      double resolved = 0);

// ---- the convergence study ------------------------------------------------------------------
struct ConvergenceRow {
  std::string model, formulation;
  std::vector<int> levels;
  std::vector<std::size_t> tets;
  std::vector<double> errors;  // relative L2 against the reference, largest over frames
  // The largest displacement against the reference's, signed (+: overshoot), at the last frame.
  std::vector<double> max_displacement_errors;
  // Observed order between consecutive levels: log(e_k / e_k+1) / log(h_k / h_k+1), h = tets^(-1/3)
  // (log2 of the error ratio for a uniform refinement); NaN when undefined.
  std::vector<double> orders;
};
struct ConvergenceResult {
  TradeReference reference;
  std::string coarser;
  std::vector<ConvergenceRow> rows;
};
// Static FEM rows, per model in options.models (springs left out) and formulation in
// options.formulations, solved directly at each of options.resolutions (default 0, 1, 2 with the
// reference one above, while it stays within max_reference_tets; -1 added when that leaves one).
ConvergenceResult run_convergence(const Scene& scene, const TradeOptions& options);
// The table `incise trade --convergence` prints: one line per row, errors per level, orders.
std::string convergence_table(const ConvergenceResult& result);

}  // namespace incise
