// incise simulate SCENE.json -o DIR: plays a scene (docs/scene.md) and writes one VTU per
// frame, a ParaView series (frames.pvd) and stats.csv.

#include <atomic>
#include <csignal>
#include <cstring>
#include <iostream>
#include <memory>

#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "mesh/errors.h"
#include "mesh/io/atomic_file.h"
#include "scene/run_directory.h"
#include "scene/run_scene.h"
#include "scene/scene_runner.h"
#include "sim/petsc/petsc_session.h"

namespace incise::cli {

namespace {

// SIGINT, SIGTERM or SIGHUP during a run: the run stops before its next frame (the frames so far
// are kept as after any error, the hidden run directory removed). A second one acts as usual.
std::atomic<int> g_signal{0};
extern "C" void on_stop_signal(int s) {
  g_signal.store(s);
  std::signal(s, SIG_DFL);
}

// Rank 0 of `mpirun -np N incise simulate`: however the run ends, the serving ranks learn its
// status (1 on an exception) and exit with it.
struct ReleaseServingRanks {
  ~ReleaseServingRanks() { petsc_finish(std::uncaught_exceptions() > 0 ? 1 : 0); }
};

}  // namespace

void add_simulate(CLI::App& app) {
  struct Opts {
    std::string scene, out;
    int frames = -1;
    bool quiet = false, json = false;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("simulate", "Run a simulation scene (JSON, see docs/scene.md)");
  cmd->add_option("scene", o->scene, "Scene file (.json)")->required();
  cmd->add_option("-o,--output", o->out, "Output directory: frame_NNNN.vtu, frames.pvd, stats.csv")->required();
  cmd->add_option("--frames", o->frames, "Override the scene's number of frames (at least 1)")
      ->check(CLI::Range(1, 1000000000));
  cmd->add_flag("-q,--quiet", o->quiet, "No per-frame progress on stderr");
  cmd->add_flag("--json", o->json, "Print the summary as JSON on stdout");
  cmd->callback([o] {
    // Under mpirun the ranks other than 0 serve rank 0's PETSc solves (scene solver.backend
    // "petsc", docs/solver.md#petsc-more-than-one-machine); rank 0 plays the scene and writes the files as one process does.
    if (petsc_start_distributed() != 0) std::exit(petsc_serve());
    ReleaseServingRanks release;
    check_output_dir(o->out);
    const Scene scene = load_scene(o->scene);
    SceneRunOptions ro;
    ro.frames = o->frames;
    ro.progress = o->quiet ? nullptr : &std::cerr;
    for (int s : {SIGINT, SIGTERM, SIGHUP}) std::signal(s, on_stop_signal);
    ro.before_frame = [](SceneRunner&) {
      if (const int s = g_signal.load())
        throw Error("simulate: interrupted by signal " + std::to_string(s) + " (" + ::strsignal(s) + ")");
    };
    const SceneRunSummary s = run_scene_into(scene, ro, o->out);
    for (const std::string& w : s.warnings) std::cerr << "incise: warning: " << o->scene << ": " << w << "\n";
    nlohmann::json cuts = nlohmann::json::array();
    for (const auto& c : s.cuts)
      cuts.push_back({{"tets_cut", c.tets_cut}, {"faces_opened", c.faces_opened}, {"parts", c.parts}});
    if (o->json) {
      nlohmann::json j = {{"scene", o->scene},
                          {"output", o->out},
                          {"vertices", s.vertices},
                          {"tets", s.tets},
                          {"frames", s.frames},
                          {"total_iterations", s.total_iterations},
                          {"total_solve_ms", s.total_solve_ms},
                          {"frames_budget_exhausted", s.frames_budget_exhausted},
                          {"frames_not_converged", s.frames_not_converged},
                          {"max_displacement", s.max_displacement},
                          {"max_inverted", s.max_inverted},
                          {"frames_with_inverted", s.frames_with_inverted},
                          {"first_stable_dt", s.first_stable_dt},
                          {"min_stable_dt", s.min_stable_dt},
                          {"estimated_stable_dt", s.estimated_stable_dt},
                          {"total_cut_ms", s.total_cut_ms},
                          {"fragments_handled", s.fragments_handled},
                          {"cuts", cuts},
                          {"files", s.files.size()},
                          {"warnings", s.warnings}};
      std::cout << j.dump(2) << "\n";
    } else {
      std::cout << "simulate: " << s.frames << " frames on " << s.vertices << " vertices / " << s.tets << " tets, "
                << s.total_iterations << " CG iterations, " << s.total_solve_ms << " ms solving, "
                << s.frames_budget_exhausted << " frames stopped by the budget, " << s.frames_not_converged
                << " not converged; max displacement " << s.max_displacement << "; "
                << (s.frames_with_inverted == 0 ? std::string("no inverted tets")
                                                : std::to_string(s.frames_with_inverted) + " frames with inverted tets (at most " +
                                                      std::to_string(s.max_inverted) + ")")
                << (scene.cuts.empty() ? "" : "; cutting " + std::to_string(s.total_cut_ms) + " ms") << "; "
                << s.files.size() << " files in "
                << o->out << "\n";
      if (s.min_stable_dt > 0)
        std::cout << "simulate: springs' stable explicit step " << s.first_stable_dt << " s at the start, "
                  << s.min_stable_dt << " s at the smallest (cuts make smaller tets), bounds at rest; "
                  << s.estimated_stable_dt << " s at the last frame, estimated from its fastest mode\n";
      // What each scene cut did (a cut that met nothing is also a warning above).
      for (std::size_t i = 0; i < s.cuts.size(); ++i)
        std::cout << "simulate: cuts[" << i << "]: " << s.cuts[i].tets_cut << " tets cut, " << s.cuts[i].faces_opened
                  << " faces opened, " << s.cuts[i].parts << " parts detached\n";
    }
  });
}

}  // namespace incise::cli
