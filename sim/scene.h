#pragma once
// Scenes: a JSON file that says which mesh, which model, which materials, constraints, loads
// and probes over time, which solver, how many frames; and the runner that plays it and writes
// one VTU per frame, a ParaView .pvd series and stats.csv. The format is documented in
// docs/scene.md (a user-facing contract: names and meanings do not change).
//
// Errors name the scene file and the key: "beam.json: solver.tolerance: expected a positive
// number". Everything is checked (including that every box selects vertices) before any
// output is written. A scene builds only what it uses (no assembled matrix, factorization or
// spring network unless asked for).
#include <array>
#include <functional>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include "mesh/tet_mesh.h"
#include "mesh/topology_change.h"
#include "sim/fem_simulation.h"
#include "sim/formulation.h"
#include "sim/material.h"

namespace incise {

struct SceneBox {
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
  bool contains(const Vec3& p, double tol) const {
    return (p.array() >= lo.array() - tol).all() && (p.array() <= hi.array() + tol).all();
  }
};

// Vertices in `box` held on the axes in `axes` (bit 0: x, 1: y, 2: z): all three fix them, one or
// two make rollers (a symmetry plane, a plane-strain end face).
struct SceneFixed {
  SceneBox box;
  unsigned axes = 7;
};

struct SceneLoad {
  enum class Kind { Force, Gravity, Probe, Pressure } kind = Kind::Force;
  std::string key;           // "loads[2]", for messages
  SceneBox box;              // force, probe; pressure when tag < 0
  int tag = -1;              // pressure: the boundary faces with this tag (instead of a box)
  Vec3 value = Vec3::Zero(); // force: total [N]; gravity: g [m/s^2]; probe: displacement [m]; pressure: (p [Pa], 0, 0)
  int from_frame = 0;        // probe (and optionally force): ramp start
  int to_frame = 0;          // ramp end (== from_frame: a step)
  bool ramp = false;         // force: ramped only when from_frame/to_frame are given
  // Ramp factor in [0, 1] at `frame`.
  double factor(int frame) const;
};

enum class SceneModel { FemLinear, FemCorotational, Springs };

// A blade cut over frames: segment a-b moves by `sweep`, linearly from frame `from_frame` to
// `to_frame` (one cut step per frame; equal frames: the whole sweep before that frame's solve).
// Before frame k's solve it has swept (k - from + 1) / (to - from + 1) of it, where a probe
// ramped over the same frames applies (k - from) / (to - from) (docs/scene.md).
struct SceneCut {
  std::string key;              // "cuts[0]", for messages
  Vec3 a = Vec3::Zero(), b = Vec3::Zero(), sweep = Vec3::Zero();
  int from_frame = 0, to_frame = 0;
  std::string mode = "subdivide";  // or "remove"
  double snap = 0.05;
  bool improve = true;
};

// What a part that a cut detached (and that holds no fixed or prescribed vertex) becomes.
// Keep is for dynamic scenes (the part falls): a static FEM scene has no equilibrium for a free
// part, so one that would keep it is refused with an Error naming the frame.
enum class FragmentPolicy { Auto, Keep, Fix, Remove, Error };

// What a scene's cuts did before one frame. Cutting lives in cut/, which sim does not depend
// on: the runner calls a hook (cut/scene_cuts.h provides it) with the current positions and a
// function that hands each cut step's TopologyChange to the backend (so the next blade of the
// same frame sees the new vertices' current positions), and a bound on how far any vertex is
// from its rest position (the cutter's first-contact grid lives in rest space; an O(V) pass,
// so the hook asks for it only in frames where a blade moves).
struct SceneCutResult {
  double ms = 0;                              // cut steps (cut + local improvement)
  std::vector<std::vector<TetId>> fragments;  // detached parts (tets), as the cutter found them
};
using SceneCutHook = std::function<SceneCutResult(int frame, TetMesh& mesh, const std::function<Vec3(VertexId)>& current,
                                                  const std::function<double()>& max_displacement,
                                                  const std::function<void(const TopologyChange&)>& apply)>;

struct Scene {
  std::string path;                 // the scene file (messages, relative paths)
  // Mesh: a file (relative to the scene) or a generator.
  std::string mesh_file;
  std::string generator;            // "", "box", "ellipsoid" or "tube"
  Vec3 gen_size = Vec3::Ones();     // box size, ellipsoid radii, tube (inner radius, outer radius, height)
  std::array<int, 3> gen_cells{4, 4, 4};  // box; tube (across the wall, around, along)
  double gen_angle = 90;            // tube: sector angle [deg]
  int gen_resolution = 4;
  SceneModel model = SceneModel::FemLinear;
  Formulation formulation = Formulation::Standard;  // FEM: how the volumetric strain is treated
  MaterialTable materials;
  std::vector<SceneFixed> fixed;
  std::vector<SceneLoad> loads;
  // solver
  SolverMethod method = SolverMethod::Cg;
  StiffnessBackend backend = StiffnessBackend::MatrixFree;
  CgOptions cg{.preconditioner = Preconditioner::Cholesky};  // the fastest measured (docs/solver.md)
  bool warm_start = true;
  bool predict = true;              // warm start extrapolates the last frames ("predict")
  int nonlinear_iterations = 1;
  AsyncCholeskyOptions cholesky;    // the cholesky preconditioner's policy (library and benches)
  AggregationAmgOptions amg;        // the amg preconditioner's options (library and benches)
  // time
  int frames = 100;
  double dt = 0.01;
  std::string integrator;           // "" = model default (fem: static; springs: symplectic-euler)
  double damping = 0;
  int substeps = 1;                 // springs: steps per frame
  // cuts
  std::vector<SceneCut> cuts;
  FragmentPolicy fragments = FragmentPolicy::Auto;  // Auto: remove for static FEM, keep otherwise
  // output
  int output_every = 1;
  bool output_binary = true;
};

// Throws IoError(path, line, reason) for unreadable files and malformed JSON, and
// IoError(path, 0, "key: expected ...") for bad content.
Scene load_scene(const std::string& path);
Scene parse_scene(const std::string& json_text, const std::string& path);

struct SceneRunOptions {
  std::string out_dir;                // created if missing; empty: write nothing
  int frames = -1;                    // override scene frames when >= 0
  std::ostream* progress = nullptr;   // one line per frame (stderr in the CLI)
  SceneCutHook cut_hook;              // required when the scene has cuts (cut/scene_cuts.h)
  // Called after each frame with its displacement (3 per vertex slot) and stats (incise trade).
  std::function<void(int frame, const Eigen::VectorXd& displacement, const FrameStats& stats)> on_frame;
  // Checked after on_frame: true ends the run after this frame (incise trade: a dynamic run
  // that has settled).
  std::function<bool(int frame)> stop;
  // Plays the scene on this mesh instead of its own (incise trade: other resolutions of the
  // same body); the scene's boxes select on it the same way. Copied, not modified.
  const TetMesh* mesh = nullptr;
};

struct SceneRunSummary {
  int frames = 0;
  long total_iterations = 0;
  double total_solve_ms = 0;
  int frames_budget_exhausted = 0;
  int frames_not_converged = 0;
  double total_cut_ms = 0;
  std::size_t fragments_handled = 0;  // detached parts the policy fixed or removed (kept ones are not counted)
  double max_displacement = 0;        // at the last frame
  std::size_t vertices = 0, tets = 0;
  std::vector<std::string> files;     // written, relative to out_dir
};

// Loads the mesh, builds the model and plays the frames. Throws Error naming the scene, the
// frame and the reason on a solver breakdown, on a solution that blew up (NaN/Inf, or a vertex
// moved by more than 1000 times the body's size: never reported as converged), and when a
// static FEM scene would keep a part a cut freed.
SceneRunSummary run_scene(const Scene& scene, const SceneRunOptions& options);

}  // namespace incise
