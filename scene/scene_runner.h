#pragma once
// SceneRunner: plays a scene (scene/scene.h) one frame at a time. It owns the mesh, the backend
// the scene asks for (FEM or springs) and a Cutter per scene blade; step() plays the next frame
// (the blades due at it, the loads and probes at it, the solve) and returns its stats and
// displacement. Between frames, input can come from outside (live mode: a viewer's blade and
// probe, a script): advance_blade()/finish_blade() cut the current (deformed) shape, set_probe()
// holds vertices displaced, edit() takes any other mesh edit. Every topology change reaches the
// backend (locally, one TopologyChange each) and the other cutters' first-contact grids, and a
// part a cut detached follows the scene's "fragments" policy, whoever cut it.
//
//   SceneRunner run(load_scene("beam.json"));
//   for (int k = 0; k < run.scene().frames; ++k) {
//     run.advance_blade({a, b});            // optional, from outside
//     SceneFrame f = run.step();            // f.displacement, f.stats
//   }
//
// run_scene (scene/run_scene.h) is this loop plus the output files; `incise simulate`,
// `incise trade` and Python's run_scene go through it.
#include <functional>
#include <memory>
#include <vector>

#include "cut/blade.h"
#include "cut/cutter.h"
#include "scene/scene.h"
#include "sim/fem/fem_simulation.h"
#include "sim/springs/integrator.h"
#include "sim/springs/spring_model.h"

namespace incise {

// A vertex's share of the boundary faces a pressure or traction load selects: a third of each
// incident selected face's rest area, as the outward area vector and as its magnitude.
struct FaceShare {
  VertexId vertex;
  Vec3 area_vector;
  double area = 0;
};

// One played frame.
struct SceneFrame {
  int frame = 0;
  double time = 0;                  // dynamic: simulated seconds at the frame's end; static: the frame number
  FrameStats stats;                 // springs: iterations and residual of the implicit solves, timings
  Eigen::VectorXd displacement;     // 3 per vertex slot (dead slots: 0)
  double max_displacement = 0;      // largest vertex displacement
  double cut_ms = 0;                // the scene's blades before the solve (cut + local improvement)
  double cut_improve_ms = 0;        // of cut_ms: the local improvement
  std::size_t inverted = 0;         // tets inverted or flat in the deformed shape
  double stable_dt = 0;             // springs: the explicit step's stable bound after the frame's cuts
};

class SceneRunner {
public:
  // A withdrawn blade's improvement (Cutter::finish, CutOptions::finish_improve_work
  // operations) runs at most this many operations a frame, the rest in the frames after: all
  // of it in one frame stalled that frame (README, "When a blade is withdrawn").
  static constexpr int kFinishImproveSlice = 100;
  // Under solver.budget_ms the scene's own blades' improvement (each step's and each finish
  // slice) also stops after this share of the budget: an operation count is a time only on one
  // machine (a slice could take more than a 16 ms frame; docs/cut.md#the-defaults). An outside
  // blade (blade_step, the viewer's) keeps operation counts alone: a take
  // must replay to the same mesh.
  static constexpr double kCutImproveShareOfBudget = 0.25;

  // Builds the mesh (a copy of `mesh` when given: other resolutions of the same body, with the
  // scene's boxes selecting on it the same way), selects every box, builds the model. Throws
  // IoError naming the key when a box selects nothing or a static solve is under-constrained.
  explicit SceneRunner(const Scene& scene, const TetMesh* mesh = nullptr);
  ~SceneRunner();
  SceneRunner(const SceneRunner&) = delete;  // the cutters and the backend hold the mesh's address
  SceneRunner& operator=(const SceneRunner&) = delete;

  // Plays frame(): its blades, loads and probes, the solve; then frame() moves on. Throws Error
  // naming the scene, the frame and the reason on a solver breakdown, on a solution that blew
  // up (NaN/Inf, or a vertex moved by more than 1000 times the body's size), and when a static
  // FEM scene would keep a part a cut freed.
  SceneFrame step();

  // ---- input between frames -------------------------------------------------------------
  // A blade from outside, on the current shape: the first call places it (a new cut; `options`
  // apply to it), later calls cut what it sweeps from its last position (cut/cutter.h). Detached parts follow the
  // scene's fragment policy at once (named as before frame()). Returns the step's report
  // (its fragments moved out).
  CutStepReport advance_blade(const BladeSegment& blade, const CutOptions& options = {});
  // The blade is withdrawn: its front gets the cutter's final improvement. No-op without one.
  CutStepReport finish_blade();
  // Holds `vertices` at their rest position plus `displacement` from the next step on (FEM:
  // prescribed; springs: the target position), replacing the previous outside probe. Vertices
  // the scene already holds (fixed boxes, its probes, fixed fragments) are left to the scene.
  void set_probe(const std::vector<VertexId>& vertices, const Vec3& displacement);
  // Lets the probed vertices go (free again from the next step).
  void release_probe();
  // A probe as a hand gives it: grabs the live vertices within `radius` of `point` (current
  // positions; O(mesh), once per grab) and holds them where they are; move_probe() then holds
  // them displaced by `displacement` from there. Returns how many it grabbed.
  std::size_t grab_probe(const Vec3& point, double radius);
  void move_probe(const Vec3& displacement);

  // ---- recording ----------------------------------------------------------------------------
  // Every input applied so far, outside (advance_blade, finish_blade, grab_probe, move_probe,
  // release_probe) and replayed from the scene's "inputs", in the order applied, each with the
  // frame it came before: a scene's "inputs" list (scene/scene_record.h) that replays this run.
  const std::vector<SceneInput>& inputs_applied() const { return applied_; }
  // False once an input a scene cannot say was given (set_probe() with a list of vertices,
  // edit(), advance_blade() with options a scene input has no key for).
  bool replayable() const { return replayable_; }
  // Any other edit of the mesh: `edit` changes it (its change record is taken afterwards) and
  // returns the parts it detached, as the cutter reports them; the backend and the blades take
  // the change and the fragment policy decides the parts.
  void edit(const std::function<std::vector<std::vector<TetId>>(TetMesh&)>& edit);

  // Called with every change of the mesh after the backend took it (scene and outside blades,
  // edits, removed fragments): what a viewer needs to keep its copy of the boundary up to date
  // locally. One observer; an empty function removes it.
  void set_change_observer(std::function<void(const TopologyChange&)> observer) { observer_ = std::move(observer); }

  // ---- state ------------------------------------------------------------------------------
  const Scene& scene() const { return scene_; }
  int frame() const { return frame_; }                  // the next frame step() plays
  const TetMesh& mesh() const { return mesh_; }
  FemSimulation* fem() { return fem_.get(); }            // null for a springs scene
  const FemSimulation* fem() const { return fem_.get(); }
  SpringModel* springs() { return springs_.get(); }      // null for an FEM scene
  const SpringModel* springs() const { return springs_.get(); }
  bool dynamic() const { return dynamic_; }
  Vec3 position(VertexId v) const;                       // current (deformed) position
  std::vector<Vec3> positions() const;                   // per vertex slot (dead slots: zero)
  // Live vertices whose current position is within `radius` of `point` (what a probe grabs).
  std::vector<VertexId> vertices_near(const Vec3& point, double radius) const;
  double body_size() const { return size_; }            // the rest bounding box's diagonal
  // The vertices the scene's loads act on: force and probe boxes, pressure and traction faces
  // (gravity acts everywhere and is not listed). Each once, in no particular order.
  std::vector<VertexId> loaded_vertices() const;
  double total_cut_ms() const { return total_cut_ms_; }
  std::size_t fragments_handled() const { return fragments_handled_; }  // fixed or removed parts
  // Per scene cut, so far: the tets it split or removed (0 after its last frame: it missed), the
  // faces it opened (pairs) and the parts it detached.
  struct CutTally {
    std::size_t tets_cut = 0, faces_opened = 0, parts = 0;
  };
  const std::vector<CutTally>& cut_tallies() const { return cut_tallies_; }

private:
  void apply_change(const TopologyChange& change, const Cutter* from);
  double max_displacement_bound() const;
  // `body`: a cutter's report's body (CutStepReport::body), handled too when it holds nothing
  // while one of `parts` does.
  void handle_fragments(std::vector<std::vector<TetId>> parts, std::vector<TetId> body = {});
  CutStepReport took_blade_step(CutStepReport r);  // an outside blade step: change, time, fragments
  bool held_by_scene(VertexId v) const;
  double cut_scene_blades(double& improve_ms);
  void replay_inputs();  // the scene's inputs due before this frame
  CutStepReport blade_step(const BladeSegment& blade, const CutOptions& options);
  void record(SceneInput in);
  static CutOptions cut_options(const SceneInput& in);
  double improve_time_cap() const;
  void hold_probe(const std::vector<VertexId>& vertices, const Vec3& displacement);
  void free_probe();

  Scene scene_;
  TetMesh mesh_;
  double size_ = 0;
  std::unique_ptr<FemSimulation> fem_;
  std::unique_ptr<SpringModel> springs_;
  Integrator integrator_ = Integrator::SymplecticEuler;
  bool dynamic_ = false;
  FragmentPolicy policy_ = FragmentPolicy::Keep;
  std::vector<std::vector<VertexId>> load_vertices_;                      // per load (force, probe)
  std::vector<std::vector<FaceShare>> face_shares_;  // per pressure or traction load
  // Quadratic tets: per pressure or traction load its faces (empty otherwise).
  std::vector<std::vector<std::array<VertexId, 3>>> face_lists_;
  std::vector<std::unique_ptr<Cutter>> cutters_;  // per scene cut
  std::vector<double> swept_;                     // per scene cut: fraction of its sweep done
  std::vector<CutTally> cut_tallies_;             // per scene cut
  std::unique_ptr<Cutter> blade_;                 // the outside blade
  std::vector<VertexId> probe_;                   // the outside probe's vertices
  Vec3 probe_displacement_ = Vec3::Zero();
  Vec3 probe_base_ = Vec3::Zero();                // where grab_probe() found its vertices (mean displacement)
  std::vector<SceneInput> applied_;
  std::size_t next_input_ = 0;                    // the scene's next input to replay
  bool replayable_ = true;
  std::vector<Vec3> force_;
  int frame_ = 0;
  double total_cut_ms_ = 0;
  double outside_ms_ = 0;  // outside blade steps since the last frame: taken off its solver budget
  std::size_t fragments_handled_ = 0;
  std::function<void(const TopologyChange&)> observer_;
};

}  // namespace incise
