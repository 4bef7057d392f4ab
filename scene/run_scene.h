#pragma once
// run_scene: plays a whole scene (scene/scene_runner.h, frame by frame) and writes one VTU per
// frame, a ParaView .pvd series and stats.csv (scene/scene_output.h). What `incise simulate`,
// `incise trade` and Python's run_scene call.
#include <functional>
#include <iosfwd>
#include <string>
#include <vector>

#include "scene/scene.h"

namespace incise {

class SceneRunner;

struct SceneRunOptions {
  std::string out_dir;                // created if missing; empty: write nothing
  int frames = -1;                    // override scene frames when >= 0
  std::ostream* progress = nullptr;   // one line per frame (stderr in the CLI)
  // Called before each frame's step (runner.frame() is that frame): input from outside the
  // scene between frames (a blade, a probe, an edit: scene/scene_runner.h).
  std::function<void(SceneRunner& runner)> before_frame;
  // Called after each frame with its displacement (3 per vertex slot) and stats (incise trade).
  std::function<void(int frame, const Eigen::VectorXd& displacement, const FrameStats& stats)> on_frame;
  // Checked after on_frame: true ends the run after this frame (incise trade: a dynamic run
  // that has settled).
  std::function<bool(int frame)> stop;
  // Plays the scene on this mesh instead of its own (incise trade: other resolutions of the
  // same body); the scene's boxes select on it the same way. Copied, not modified.
  const TetMesh* mesh = nullptr;
  // A median frame above this (ms; the first frame, which builds the solver, aside) is not
  // interactive: the summary warns and names `incise trade`. 0: never.
  double slow_frame_ms = 100;
};

struct SceneRunSummary {
  int frames = 0;
  long total_iterations = 0;
  double total_solve_ms = 0;
  int frames_budget_exhausted = 0;
  int frames_not_converged = 0;
  double total_cut_ms = 0;
  std::size_t fragments_handled = 0;
  // Per scene cut: tets it split or removed, faces it opened (pairs), parts it detached.
  struct Cut {
    std::size_t tets_cut = 0, faces_opened = 0, parts = 0;
  };
  std::vector<Cut> cuts;  // detached parts the policy fixed or removed (kept ones are not counted)
  double max_displacement = 0;        // at the last frame
  // Tets inverted or flat in the deformed shape (stats.csv's `inverted`): the most in one frame,
  // and how many frames had any.
  std::size_t max_inverted = 0;
  int frames_with_inverted = 0;
  // Springs: the explicit step's stable bound (stats.csv stable_dt) at the first frame and its
  // smallest over the run (cuts lower it); 0 for FEM.
  double first_stable_dt = 0, min_stable_dt = 0;
  // Springs: the stable step at the last frame from an estimate of its fastest mode
  // (SpringModel::estimated_stable_time_step: tight, and it sees the state); 0 for FEM.
  double estimated_stable_dt = 0;
  std::size_t vertices = 0, tets = 0;
  std::vector<std::string> files;     // written, relative to out_dir
  // What the user should know although nothing failed, one line each: a scene cut whose blade
  // met no tet over all its frames ("cuts[0] (frames 10-30) cut nothing: ..."), standard tets
  // at a Poisson's ratio where they lock, frames too slow to be interactive (slow_frame_ms).
  std::vector<std::string> warnings;
};

// Loads the mesh, builds the model and plays the frames, the scene's cuts included. Throws
// Error naming the scene, the frame and the reason on a solver breakdown, on a solution that
// blew up (NaN/Inf, or a vertex moved by more than 1000 times the body's size: never reported
// as converged), and when a static FEM scene would keep a part a cut freed; the frames computed
// before stay written.
SceneRunSummary run_scene(const Scene& scene, const SceneRunOptions& options);

}  // namespace incise
