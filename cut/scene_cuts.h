#pragma once
// Scenes with cuts: runs a scene (sim/scene.h) whose "cuts" list moves blades over frames.
// Each cut gets a Cutter; before each frame's solve every active blade advances to its position
// at that frame (linear from from_frame to to_frame), cutting the current (deformed) shape.
#include "sim/scene.h"

namespace incise {

// The hook run_scene calls before each frame (for callers that drive run_scene themselves).
SceneCutHook make_scene_cut_hook(const Scene& scene);

// run_scene with the scene's cuts (the same as run_scene for a scene without cuts).
SceneRunSummary run_scene_with_cuts(const Scene& scene, SceneRunOptions options);

}  // namespace incise
