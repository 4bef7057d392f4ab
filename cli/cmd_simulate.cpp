// incise simulate SCENE.json -o DIR: plays a scene (docs/scene.md) and writes one VTU per
// frame, a ParaView series (frames.pvd) and stats.csv.
#include <fcntl.h>
#include <stdio.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <regex>

#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "mesh/errors.h"
#include "mesh/io/atomic_file.h"
#include "scene/run_scene.h"

namespace incise::cli {

namespace {

namespace fs = std::filesystem;

// What a run writes into DIR; anything else there is the user's and makes the run refuse DIR.
bool is_run_output(const std::string& name) {
  static const std::regex kRun(R"(frame_\d+\.(vtu|vtk)|frames\.pvd|stats\.csv)");
  return std::regex_match(name, kRun);
}

// DIR is always one run's output: the run goes to a fresh directory beside DIR (in DIR's
// nearest existing ancestor, so the final rename stays on one file system) and replaces DIR
// only at the end. A shorter re-run leaves no stale frames; a failed run leaves DIR as it was.
class RunDirectory {
public:
  explicit RunDirectory(const std::string& out) : out_(out), dir_(fs::absolute(out).lexically_normal()) {
    if (!dir_.has_filename()) dir_ = dir_.parent_path();  // "out/" -> "out"
    check_output_dir(out);
    std::error_code ec;
    existed_ = fs::is_directory(dir_, ec);
    if (existed_) {
      for (const auto& e : fs::directory_iterator(dir_)) {
        const std::string name = e.path().filename().string();
        if (!is_run_output(name))
          throw IoError(out, 0, "holds " + name + ", which incise simulate did not write; give a new or empty directory");
        had_run_ = true;
      }
    }
    fs::path base = dir_.parent_path();
    while (!fs::exists(base, ec)) base = base.parent_path();
    for (int attempt = 0;; ++attempt) {
      tmp_ = base / ("." + dir_.filename().string() + ".run" + std::to_string(::getpid()) + "_" + std::to_string(attempt));
      if (fs::create_directory(tmp_, ec)) break;
      if (ec || attempt > 100) throw IoError(out, 0, "cannot create a run directory beside it: " + tmp_.string());
    }
  }
  ~RunDirectory() {
    std::error_code ec;
    if (!tmp_.empty()) fs::remove_all(tmp_, ec);
  }
  RunDirectory(const RunDirectory&) = delete;
  RunDirectory& operator=(const RunDirectory&) = delete;

  std::string path() const { return tmp_.string(); }
  // Whether DIR holds an earlier run (which a failed run must not replace).
  bool holds_earlier_run() const { return had_run_; }

  // Puts the run in DIR: an atomic exchange when DIR exists, the earlier run then removed.
  void commit() {
    std::error_code ec;
    fs::create_directories(dir_.parent_path(), ec);
    if (ec) throw IoError(out_, 0, "cannot create output directory: " + ec.message());
    if (existed_ && fs::is_directory(dir_, ec)) {
      if (::renameat2(AT_FDCWD, tmp_.c_str(), AT_FDCWD, dir_.c_str(), RENAME_EXCHANGE) != 0) {
        // No RENAME_EXCHANGE on this file system: DIR is missing only between two renames.
        const fs::path old = tmp_.string() + ".old";
        if (std::rename(dir_.c_str(), old.c_str()) != 0 || std::rename(tmp_.c_str(), dir_.c_str()) != 0) {
          const int err = errno;
          if (!fs::exists(dir_, ec)) std::rename(old.c_str(), dir_.c_str());
          throw IoError(out_, 0, std::string("cannot replace the directory: ") + std::strerror(err));
        }
        fs::remove_all(old, ec);
        return;  // tmp_ is gone (renamed); the destructor removes nothing
      }
    } else if (std::rename(tmp_.c_str(), dir_.c_str()) != 0) {
      throw IoError(out_, 0, std::string("cannot move the run into place: ") + std::strerror(errno));
    }
  }

private:
  std::string out_;
  fs::path dir_, tmp_;
  bool existed_ = false, had_run_ = false;
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
    check_output_dir(o->out);
    const Scene scene = load_scene(o->scene);
    RunDirectory run(o->out);
    SceneRunOptions ro;
    ro.out_dir = run.path();
    ro.frames = o->frames;
    ro.progress = o->quiet ? nullptr : &std::cerr;
    SceneRunSummary s;
    try {
      s = run_scene(scene, ro);
    } catch (const Error& e) {
      // The frames computed before the failure are kept (docs/scene.md) unless DIR holds an
      // earlier run: that one is not replaced by a broken one.
      if (run.holds_earlier_run())
        throw Error(std::string(e.what()) + " (" + o->out + " keeps the earlier run)");
      run.commit();
      throw;
    }
    run.commit();
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
                          {"total_cut_ms", s.total_cut_ms},
                          {"fragments_handled", s.fragments_handled},
                          {"files", s.files.size()}};
      std::cout << j.dump(2) << "\n";
    } else {
      std::cout << "simulate: " << s.frames << " frames on " << s.vertices << " vertices / " << s.tets << " tets, "
                << s.total_iterations << " CG iterations, " << s.total_solve_ms << " ms solving, "
                << s.frames_budget_exhausted << " frames stopped by the budget, " << s.frames_not_converged
                << " not converged; max displacement " << s.max_displacement
                << (scene.cuts.empty() ? "" : "; cutting " + std::to_string(s.total_cut_ms) + " ms") << "; "
                << s.files.size() << " files in "
                << o->out << "\n";
    }
  });
}

}  // namespace incise::cli
