// incise trade SCENE -o DIR: the scene under a grid of resolutions, models, formulations and
// solver settings, each measured for time per frame and error against a converged reference
// (docs/solver.md); writes DIR/trade.csv and DIR/trade.svg (and --json), progress on stderr,
// the frontier and one recommendation per frame budget on stdout.
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <memory>

#include "cli/commands.h"
#include "mesh/errors.h"
#include "mesh/io/atomic_file.h"
#include "mesh/io/tet_io.h"
#include "sim/fem/formulation.h"
#include "scene/trade.h"
#include "sim/petsc/petsc_session.h"
#include "sim/springs/spring_model.h"

namespace incise::cli {

namespace {

SceneModel parse_model(const std::string& m) {
  if (m == "fem-linear") return SceneModel::FemLinear;
  if (m == "fem-corotational") return SceneModel::FemCorotational;
  if (m == "springs") return SceneModel::Springs;
  throw InvalidArgument("trade: --models: expected fem-linear, fem-corotational or springs, got \"" + m + "\"");
}

}  // namespace

struct TradeCliOptions {
  std::string scene, out;
  int frames = -1;
  std::vector<std::string> models{"fem-linear", "fem-corotational", "springs"};
  std::vector<std::string> formulations{"standard", "nodal-averaged", "mixed"};
  std::vector<std::string> spring_volumes{"tet", "nodal"};
  std::vector<std::string> spring_stiffness{"van-gelder", "fitted"};
  std::vector<std::string> spring_connectivity{"edges", "across-faces"};
  std::vector<double> spring_nodal_shares;
  std::vector<int> resolutions;
  int reference_level = -1;
  std::vector<double> frame_budgets{2, 16, 33};
  std::string json;
  std::vector<std::string> preconditioners{"jacobi", "block-jacobi", "cholesky", "amg"};
  std::vector<double> tolerances{1e-2, 1e-4, 1e-6, 1e-8};
  std::vector<double> budgets{0, 2};
  bool no_direct = false, quiet = false, convergence = false;
};

// One process's part of a run (all of it without mpirun): rank 0 writes the outputs.
void trade(const TradeCliOptions& opts, int rank);

void add_trade(CLI::App& app) {
  auto o = std::make_shared<TradeCliOptions>();
  auto* cmd = app.add_subcommand("trade", "Speed against accuracy of a scene: resolutions, models, formulations and solver settings against a converged reference");
  cmd->add_option("scene", o->scene, "Scene file (.json, see docs/scene.md)")->required();
  cmd->add_option("-o,--output", o->out, "Output directory: trade.csv, trade.svg")->required();
  cmd->add_option("--frames", o->frames, "Override the scene's number of frames (at least 1)")
      ->check(CLI::Range(1, 1000000000));
  cmd->add_option("--models", o->models, "Models to run")->capture_default_str();
  cmd->add_option("--spring-volumes", o->spring_volumes,
                  "Springs' volume terms, a row each: tet (per tet), nodal (averaged at the vertices), none")
      ->capture_default_str();
  cmd->add_option("--spring-stiffness", o->spring_stiffness,
                  "Springs' constants, a row each: van-gelder (the isotropic rule), fitted (to each tet's FEM stiffness)")
      ->capture_default_str();
  cmd->add_option("--spring-connectivity", o->spring_connectivity,
                  "Springs' connectivity, a row each: edges, across-faces (a spring across every interior face too; van-gelder only)")
      ->capture_default_str();
  cmd->add_option("--spring-nodal-shares", o->spring_nodal_shares,
                  "Springs' nodal volume term: a row per share of the bulk modulus averaged at the vertices, in [0, 1] "
                  "(default: the scene's springs.nodal_share, one row)");
  cmd->add_option("--formulations", o->formulations, "FEM formulations to run (standard, nodal-averaged, edge-smoothed, mixed, mixed-edge-smoothed, quadratic, mixed-quadratic)")
      ->capture_default_str();
  cmd->add_option("--resolutions", o->resolutions,
                  "Mesh levels: 0 the scene's, k refined k times (1:8), -1 one coarser (a generated mesh with half the "
                  "cells, a mesh file coarsened as by incise coarsen); default: -1, 0, and 1 when the reference (64x "
                  "the scene's tets) has at most 50k")
      ->check(CLI::Range(-1, 3));
  cmd->add_option("--reference-level", o->reference_level,
                  "Mesh level of the reference (default: one above the finest resolution)")
      ->check(CLI::Range(0, 4));
  cmd->add_option("--frame-budgets", o->frame_budgets, "Frame budgets in ms to recommend a setting for")
      ->capture_default_str();
  cmd->add_option("--json", o->json, "Also write the rows, the reference and the recommendations as JSON");
  cmd->add_option("--preconditioners", o->preconditioners, "CG preconditioners of the solver rows")->capture_default_str();
  cmd->add_option("--tolerances", o->tolerances, "CG relative tolerances")->capture_default_str();
  cmd->add_option("--budgets", o->budgets, "Per-frame CG budgets in ms (0: none)")->capture_default_str();
  cmd->add_flag("--no-direct", o->no_direct, "Skip the direct solver runs");
  cmd->add_flag("--convergence", o->convergence,
                "Instead of the grid: per model and formulation (static, direct), the error at levels 0..2 (or "
                "--resolutions) against the reference and the observed order; DIR/convergence.csv");
  cmd->add_flag("-q,--quiet", o->quiet, "No progress on stderr");
  cmd->callback([o] {
    // Under mpirun every rank plays its share of the grid and rank 0 writes the table and the
    // plot (sim/petsc/petsc_session.h, docs/solver.md#picking-settings-for-a-scene-incise-trade).
    const int rank = petsc_start_shared();
    try {
      trade(*o, rank);
    } catch (const std::exception& e) {
      if (petsc_ranks() > 1) petsc_abort(std::string("rank ") + std::to_string(rank) + ": " + e.what());
      throw;
    }
    petsc_end_shared();
  });
}

void trade(const TradeCliOptions& opts, int rank) {
  const TradeCliOptions* o = &opts;
  {
    TradeOptions to;
    to.frames = o->frames;
    to.models.clear();
    for (const auto& m : o->models) to.models.push_back(parse_model(m));
    to.formulations.clear();
    for (const auto& f : o->formulations) {
      const auto parsed = parse_formulation(f);
      if (!parsed)
        throw InvalidArgument("trade: --formulations: expected " + std::string(kFormulationNames) + ", got \"" + f + "\"");
      to.formulations.push_back(*parsed);
    }
    for (const auto& v : o->spring_volumes)
      if (v != "tet" && v != "nodal" && v != "none")
        throw InvalidArgument("trade: --spring-volumes: expected tet, nodal or none, got \"" + v + "\"");
    if (o->spring_volumes.empty()) throw InvalidArgument("trade: --spring-volumes: expected at least one");
    to.spring_volumes = o->spring_volumes;
    for (const auto& k : o->spring_stiffness)
      if (!parse_spring_stiffness(k))
        throw InvalidArgument("trade: --spring-stiffness: expected " + std::string(kSpringStiffnessNames) + ", got \"" + k + "\"");
    if (o->spring_stiffness.empty()) throw InvalidArgument("trade: --spring-stiffness: expected at least one");
    to.spring_stiffness = o->spring_stiffness;
    for (const auto& c : o->spring_connectivity)
      if (c != "edges" && c != "across-faces")
        throw InvalidArgument("trade: --spring-connectivity: expected edges or across-faces, got \"" + c + "\"");
    if (o->spring_connectivity.empty()) throw InvalidArgument("trade: --spring-connectivity: expected at least one");
    to.spring_connectivity = o->spring_connectivity;
    for (double sh : o->spring_nodal_shares)
      if (!(sh >= 0 && sh <= 1)) throw InvalidArgument("trade: --spring-nodal-shares: expected values in [0, 1]");
    to.spring_nodal_shares = o->spring_nodal_shares;
    to.resolutions = o->resolutions;
    to.reference_level = o->reference_level;
    for (double b : o->frame_budgets)
      if (!(b > 0) || !std::isfinite(b)) throw InvalidArgument("trade: --frame-budgets: expected numbers > 0");
    to.frame_budgets_ms = o->frame_budgets;
    to.preconditioners.clear();
    for (const auto& p : o->preconditioners) {
      try {
        to.preconditioners.push_back(parse_preconditioner(p));
      } catch (const InvalidArgument& e) {
        throw InvalidArgument(std::string("trade: --preconditioners: ") + e.what());
      }
    }
    for (double t : o->tolerances)
      if (!(t > 0 && t < 1)) throw InvalidArgument("trade: --tolerances: expected numbers in (0, 1)");
    for (double b : o->budgets)
      if (!(b >= 0)) throw InvalidArgument("trade: --budgets: expected numbers >= 0");
    to.tolerances = o->tolerances;
    to.budgets_ms = o->budgets;
    to.direct = !o->no_direct;
    to.progress = o->quiet || rank != 0 ? nullptr : &std::cerr;
    to.rank = rank;
    to.ranks = petsc_ranks();
    to.gather = petsc_gather;
    // The directory is checked now and created only when there is something to put in it: a
    // scene error leaves no empty directory behind.
    check_output_dir(o->out);
    // The JSON may go into the output directory, which is created only at the end.
    if (!o->json.empty() && std::filesystem::path(o->json).parent_path().lexically_normal() !=
                                std::filesystem::path(o->out).lexically_normal())
      check_output_path(o->json);
    // Every rank reads the scene; a bad one is rank 0's one line, the others exit quietly.
    Scene scene;
    std::string failure;
    try {
      scene = load_scene(o->scene);
    } catch (const Error& e) {
      failure = e.what();
    }
    if (!petsc_all_ok(failure.empty())) {
      petsc_end_shared();  // then the usual one line (no abort: every rank knows)
      if (rank != 0) std::exit(1);
      throw Error(failure.empty() ? "trade: another rank could not read " + o->scene : failure);
    }
    // No output may be the scene or its mesh: checked before the runs.
    auto forbid_inputs = [&](OutputTransaction& t) {
      t.forbid_input(o->scene);
      if (!scene.mesh_file.empty()) forbid_tet_mesh_input(t, scene.mesh_file);
    };
    if (!o->json.empty() && std::filesystem::exists(o->json)) {  // (a new file is no input)
      OutputTransaction early;
      forbid_inputs(early);
      early.reserve(o->json, "--json");
    }
    if (o->convergence) {
      if (rank != 0) return;  // the study is one process's (a few direct solves)
      const ConvergenceResult conv = run_convergence(scene, to);
      std::error_code ec;
      std::filesystem::create_directories(o->out, ec);
      if (ec) throw IoError(o->out, 0, "cannot create output directory: " + ec.message());
      std::ostringstream csv;
      csv << "model,formulation,level,tets,error,max_displacement_error,order_to_next\n" << std::setprecision(8);
      for (const ConvergenceRow& r : conv.rows)
        for (std::size_t k = 0; k < r.levels.size(); ++k)
          csv << r.model << "," << r.formulation << "," << r.levels[k] << "," << r.tets[k] << "," << r.errors[k] << ","
              << r.max_displacement_errors[k] << "," << (k < r.orders.size() ? r.orders[k] : std::nan("")) << "\n";
      OutputTransaction tx;
      forbid_inputs(tx);
      const std::string path = (std::filesystem::path(o->out) / "convergence.csv").string();
      tx.write_text(path, csv.str());
      tx.commit();
      std::cout << convergence_table(conv) << "trade: wrote " << path << "\n";
      return;
    }
    const TradeResult result = run_trade(scene, to);
    if (rank != 0) return;
    std::error_code ec;
    std::filesystem::create_directories(o->out, ec);
    if (ec) throw IoError(o->out, 0, "cannot create output directory: " + ec.message());
    const std::filesystem::path dir(o->out);
    OutputTransaction tx;  // every file or none
    forbid_inputs(tx);
    tx.write_text((dir / "trade.csv").string(), trade_csv(result.rows));
    tx.write_text((dir / "trade.svg").string(),
                  trade_svg(result.rows, "incise trade: " + std::filesystem::path(o->scene).filename().string(),
                            to.frame_budgets_ms, std::max(result.reference.error_bar, 0.0)));
    if (!o->json.empty()) tx.write_text(o->json, trade_json(result, to.frame_budgets_ms));
    tx.commit();
    std::cout << trade_summary(result, to.frame_budgets_ms);
    std::cout << "trade: wrote " << (dir / "trade.csv").string() << " and " << (dir / "trade.svg").string()
              << (o->json.empty() ? "" : " and " + o->json) << "\n";
  }
}

}  // namespace incise::cli
