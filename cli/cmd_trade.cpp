// incise trade SCENE -o DIR: the scene under a grid of models and solver settings, each
// measured for time per frame and error against a corotational direct reference
// (docs/solver.md); writes DIR/trade.csv and DIR/trade.svg, progress on stderr.
#include <filesystem>
#include <iostream>
#include <memory>

#include "cli/commands.h"
#include "mesh/errors.h"
#include "mesh/io/atomic_file.h"
#include "sim/trade.h"

namespace incise::cli {

namespace {

SceneModel parse_model(const std::string& m) {
  if (m == "fem-linear") return SceneModel::FemLinear;
  if (m == "fem-corotational") return SceneModel::FemCorotational;
  if (m == "springs") return SceneModel::Springs;
  throw InvalidArgument("trade: --models: expected fem-linear, fem-corotational or springs, got \"" + m + "\"");
}

}  // namespace

void add_trade(CLI::App& app) {
  struct Opts {
    std::string scene, out;
    int frames = -1;
    std::vector<std::string> models{"fem-linear", "fem-corotational", "springs"};
    std::vector<std::string> preconditioners{"jacobi", "block-jacobi", "cholesky", "amg"};
    std::vector<double> tolerances{1e-2, 1e-4, 1e-6, 1e-8};
    std::vector<double> budgets{0, 2};
    bool no_direct = false, quiet = false;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("trade", "Speed against accuracy of a scene under a grid of solver settings");
  cmd->add_option("scene", o->scene, "Scene file (.json, see docs/scene.md)")->required();
  cmd->add_option("-o,--output", o->out, "Output directory: trade.csv, trade.svg")->required();
  cmd->add_option("--frames", o->frames, "Override the scene's number of frames (at least 1)")
      ->check(CLI::Range(1, 1000000000));
  cmd->add_option("--models", o->models, "Models to run")->capture_default_str();
  cmd->add_option("--preconditioners", o->preconditioners, "CG preconditioners")->capture_default_str();
  cmd->add_option("--tolerances", o->tolerances, "CG relative tolerances")->capture_default_str();
  cmd->add_option("--budgets", o->budgets, "Per-frame CG budgets in ms (0: none)")->capture_default_str();
  cmd->add_flag("--no-direct", o->no_direct, "Skip the direct solver runs");
  cmd->add_flag("-q,--quiet", o->quiet, "No progress on stderr");
  cmd->callback([o] {
    TradeOptions to;
    to.frames = o->frames;
    to.models.clear();
    for (const auto& m : o->models) to.models.push_back(parse_model(m));
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
    to.progress = o->quiet ? nullptr : &std::cerr;
    // The directory is checked now and created only when there is something to put in it: a
    // scene error leaves no empty directory behind.
    check_output_dir(o->out);
    const Scene scene = load_scene(o->scene);
    const std::vector<TradeRow> rows = run_trade(scene, to);
    std::error_code ec;
    std::filesystem::create_directories(o->out, ec);
    if (ec) throw IoError(o->out, 0, "cannot create output directory: " + ec.message());
    const std::filesystem::path dir(o->out);
    OutputTransaction tx;  // both files or neither
    tx.write_text((dir / "trade.csv").string(), trade_csv(rows));
    tx.write_text((dir / "trade.svg").string(),
                  trade_svg(rows, "incise trade: " + std::filesystem::path(o->scene).filename().string()));
    tx.commit();
    std::cout << "trade: " << rows.size() << " runs of " << o->scene << "; Pareto frontier (fastest first):\n";
    std::vector<const TradeRow*> front;
    for (const TradeRow& r : rows)
      if (r.pareto) front.push_back(&r);
    std::sort(front.begin(), front.end(), [](auto* a, auto* b) { return a->ms_per_frame < b->ms_per_frame; });
    for (const TradeRow* r : front)
      std::cout << "  " << r->model << " " << r->solver << (r->preconditioner.empty() ? "" : " " + r->preconditioner)
                << " tolerance " << r->tolerance << " budget " << r->budget_ms << " ms: " << r->ms_per_frame
                << " ms/frame, error " << r->error << "\n";
    std::cout << "trade: wrote " << (dir / "trade.csv").string() << " and " << (dir / "trade.svg").string() << "\n";
  });
}

}  // namespace incise::cli
