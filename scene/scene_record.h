#pragma once
// A run written back as a scene: the scene file's own JSON with the input a hand gave between
// frames (SceneRunner::inputs_applied(): blade steps, finishes, probe grabs and moves) as its
// "inputs" list, which `incise simulate` replays before the same frames (docs/scene.md). What
// `incise view --record` writes beside a take's frames.
#include <span>
#include <string>

#include "scene/scene.h"

namespace incise {

struct RecordedScene {
  std::span<const SceneInput> inputs;  // every input, the scene's own replayed ones included, in order
  int frames_played = 0;               // frames stepped so far
  double budget_ms = -1;               // >= 0: the solver budget the run used (replaces solver.budget_ms)
};

// The JSON text of `scene` (scene.source, its keys and order kept) with `r.inputs` as "inputs" and
// time.frames set to what the recording needs: the frames played, one more when inputs came after
// the last one. The scene's own cuts that start later are left out; one that was moving at the
// end keeps the frames to its end (the replay plays on past the recording). A mesh file's name becomes absolute,
// since the recording is read from another directory. Throws InvalidArgument when the scene has no
// source text (built in code, not read from a file).
std::string recorded_scene_json(const Scene& scene, const RecordedScene& r);

}  // namespace incise
