#pragma once
// The preparation pipeline behind `incise tetra` and `incise prepare`:
//   read (surface or labeled image) -> check -> clean -> repair when asked -> mesh.
// A surface that is not meshable as is and no repair asked: InvalidArgument whose message
// lists the findings and suggests --repair.
#include <functional>
#include <string>
#include <vector>

#include "mesh/tetrahedralize/level_set.h"
#include "mesh/tetrahedralize/surface_check.h"
#include "mesh/tetrahedralize/tetrahedralize.h"

namespace incise {

enum class TetraEngine { Cgal, Stuffing };

struct PipelineOptions {
  TetraOptions tetra;                   // sizes, criteria, optimizers, seed
  TetraEngine engine = TetraEngine::Cgal;  // Stuffing: isosurface stuffing on the level set
  bool repair = false;                  // rebuild dirty surfaces through the level set
  LevelSetOptions level_set;            // voxel size and closing radius (repair, stuffing)
};

struct PipelineReport {
  std::string input;             // path
  bool image = false;            // labeled image input (no surface check)
  SurfaceCheck check;            // surfaces only
  bool repaired = false;
  RepairReport repair;           // when repaired
  TetraStats stats;
  std::vector<std::string> messages;  // what was found and done, in order
};

// `log` receives each message as it happens (progress for the CLI); may be empty.
TetMesh mesh_file(const std::string& path, const PipelineOptions& options, PipelineReport* report = nullptr,
                  const std::function<void(const std::string&)>& log = {});

// The same from a surface in memory.
TetMesh mesh_surface(const SurfaceMesh& surface, const PipelineOptions& options, PipelineReport* report = nullptr,
                     const std::function<void(const std::string&)>& log = {});

// Isosurface stuffing (Labelle & Shewchuk 2007) of a level set; `options.size` is the BCC
// lattice spacing target. Throws Error when built without the stuffing engine.
TetMesh tetrahedralize_stuffing(const SignedDistance& sdf, const TetraOptions& options, TetraStats* stats = nullptr);

}  // namespace incise
