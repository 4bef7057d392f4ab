#pragma once
// Scenes: a JSON file that says which mesh, which model, which materials, constraints, loads
// and probes over time, which solver, how many frames, which blades cut when. This header is
// the model and its reader (scene/scene_parse.cpp); scene/scene_runner.h plays a scene one
// frame at a time, scene/run_scene.h plays all of it and writes one VTU per frame, a ParaView
// .pvd series and stats.csv. The format is documented in docs/scene.md (a user-facing
// contract: names and meanings do not change).
//
// Errors name the scene file and the key: "beam.json: solver.tolerance: expected a positive
// number". Everything is checked (including that every box selects vertices) before any
// output is written. A scene builds only what it uses (no assembled matrix, factorization or
// spring network unless asked for).
#include <array>
#include <string>
#include <vector>

#include "mesh/tet_mesh.h"
#include "sim/fem/fem_simulation.h"
#include "sim/fem/formulation.h"
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
  enum class Kind { Force, Gravity, Probe, Pressure, Traction } kind = Kind::Force;
  std::string key;           // "loads[2]", for messages
  SceneBox box;              // force, probe; pressure and traction when tag < 0
  int tag = -1;              // pressure, traction: the boundary faces with this tag (instead of a box)
  // force: total [N]; gravity: g [m/s^2]; probe: displacement [m]; pressure: (p [Pa], 0, 0);
  // traction: force per rest area [Pa]
  Vec3 value = Vec3::Zero();
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
// Or a path: the blade's ends at key frames (`path`), placed at the first before its frame's
// solve and moved to its position at each later frame up to the last key (linear between keys),
// one step per frame; from_frame/to_frame are then the first key's frame + 1 and the last's.
struct SceneCutKey {
  int frame = 0;
  Vec3 a = Vec3::Zero(), b = Vec3::Zero();
};
struct SceneCut {
  std::string key;              // "cuts[0]", for messages
  Vec3 a = Vec3::Zero(), b = Vec3::Zero(), sweep = Vec3::Zero();
  std::vector<SceneCutKey> path;  // non-empty: a path cut (a, b are its first key's; no sweep)
  int from_frame = 0, to_frame = 0;
  std::string mode = "subdivide";  // or "remove"
  double snap = 0.05;
  bool improve = true;
  bool exact_volumes = true;  // CutOptions::exact_volumes
  bool provisional = false;    // CutOptions::provisional
  bool material_frame = false;  // CutOptions::material_frame
};

// Input from outside the scene, as a viewer's blade and probe give it between frames (scene
// "inputs", docs/scene.md): `incise view --record` writes them, and SceneRunner replays them before
// frame `frame`'s solve, in the order listed, ahead of the scene's own cuts of that frame.
struct SceneInput {
  enum class Kind { Blade, Finish, Grab, Probe, Release } kind = Kind::Blade;
  int frame = 0;
  Vec3 a = Vec3::Zero(), b = Vec3::Zero();  // blade: its ends; grab: the point (a); probe: displacement (a)
  double radius = 0;                        // grab: vertices within this distance of the point
  // blade: the options of a blade that starts a cut (the first after none or a finish)
  std::string mode = "subdivide";
  double snap = 0.05;
  bool improve = true;
};

// What a part that a cut detached (and that holds no fixed or prescribed vertex) becomes.
// Keep is for dynamic scenes (the part falls): a static FEM scene has no equilibrium for a free
// part, so one that would keep it is refused with an Error naming the frame.
enum class FragmentPolicy { Auto, Keep, Fix, Remove, Error };

struct Scene {
  std::string path;                 // the scene file (messages, relative paths)
  std::string source;               // its JSON text (a recording writes it back with its inputs)
  // Mesh: a file (relative to the scene) or a generator.
  std::string mesh_file;
  std::string generator;            // "", "box", "ellipsoid", "tube" or "cook"
  Vec3 gen_size = Vec3::Ones();     // box size, ellipsoid radii, tube (inner radius, outer radius, height), cook (-, -, thickness)
  std::array<int, 3> gen_cells{4, 4, 4};  // box; tube (across the wall, around, along); cook (n, n, 1)
  double gen_angle = 90;            // tube: sector angle [deg]
  int gen_resolution = 4;
  // "" (none stated), "mm" or "m": the unit system the scene says it is in, whose ranges for
  // the body's size, the moduli, the densities and g are checked (docs/scene.md#units).
  std::string units;
  SceneModel model = SceneModel::FemLinear;
  // springs: the volume term averaged at the vertices ("nodal", default), per tet ("tet") or
  // none (SpringOptions::volume_term, ::nodal_volume; docs/solver.md#spring-volume-terms).
  // The defaults here are SpringOptions' (tests/scene/test_scene.cpp checks they agree).
  std::string springs_volume = "nodal";
  // springs, volume "nodal": the share of the bulk modulus averaged at the vertices, the rest
  // per tet (SpringOptions::nodal_share).
  double springs_nodal_share = 0.9;
  // springs: the volume ratio below which a tet's inversion guard acts (SpringOptions::inversion_guard).
  double springs_inversion_guard = 0;
  // springs: each spring's constant, "van-gelder" (default) or "fitted" to each tet's FEM
  // stiffness (SpringOptions::stiffness; docs/solver.md#spring-stiffness).
  std::string springs_stiffness = "van-gelder";
  // springs: "across-faces" (default: a spring across every interior face too) or "edges"
  // (SpringOptions::across_faces; docs/solver.md#spring-connectivity). With "fitted"
  // stiffness, which is per edge, the parser makes "edges" the default.
  std::string springs_connectivity = "across-faces";
  double springs_viscosity = 0, springs_stiffening = 0;  // SpringOptions::viscosity, ::stiffening
  // fem-corotational: hold tets near inversion (docs/solver.md#inversion-barrier-inversion_barrier-in-scenes); off by default.
  InversionBarrierOptions inversion_barrier;
  Formulation formulation = Formulation::Standard;  // FEM: how the volumetric strain is treated
  MaterialTable materials;
  std::vector<SceneFixed> fixed;
  std::vector<SceneLoad> loads;
  // solver
  SolverMethod method = SolverMethod::Cg;
  StiffnessBackend backend = StiffnessBackend::MatrixFree;  // solver.operator, or Petsc for solver.backend "petsc"
  std::string petsc_options;        // solver.petsc_options
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
  std::vector<SceneInput> inputs;   // recorded outside input, replayed (frames non-decreasing)
  FragmentPolicy fragments = FragmentPolicy::Auto;  // Auto: remove for static FEM, keep otherwise
  // output
  int output_every = 1;
  bool output_binary = true;
};

// Throws IoError(path, line, reason) for unreadable files and malformed JSON, and
// IoError(path, 0, "key: expected ...") for bad content.
Scene load_scene(const std::string& path);
Scene parse_scene(const std::string& json_text, const std::string& path);

// The scene's mesh: its file (relative to the scene file) or its generator, with no pending
// change record. Throws what the reader throws (IoError naming the file).
TetMesh load_scene_mesh(const Scene& scene);

// The scene's generator run with `cells` instead of its own counts (the ellipsoid's resolution is
// cells[0]); the generated body at another resolution (incise trade). Needs a generator.
TetMesh generate_scene_mesh(const Scene& scene, const std::array<int, 3>& cells);

}  // namespace incise
