#pragma once
// What run_scene writes into its output directory: frame_NNNN.vtu (the deformed mesh with its
// displacement, von Mises stress for FEM and, in scenes with cuts, cut faces per tet),
// frames.pvd (the ParaView series) and stats.csv (one row per frame). The columns and fields
// are part of docs/scene.md's contract.
#include <sstream>
#include <string>
#include <vector>

#include "scene/scene_runner.h"

namespace incise {

class SceneOutput {
public:
  // Creates `dir` (IoError when it cannot). Nothing else is written before finish().
  SceneOutput(const Scene& scene, std::string dir);

  // The frame's stats.csv row, and its VTU (added to the series) when `vtu`. Returns the VTU's
  // name, or "" when none was written.
  std::string add(SceneRunner& runner, const SceneFrame& frame, bool vtu);
  // Writes stats.csv and frames.pvd (each atomically): what add() collected. Returns their names.
  std::vector<std::string> finish();

private:
  std::string dir_;
  bool cuts_;     // the scene has cuts: cut_ms and tets columns, the cut_faces field
  bool springs_;  // the spring model: the stable_dt column
  bool binary_;
  std::ostringstream csv_, pvd_;
};

}  // namespace incise
