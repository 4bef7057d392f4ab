#pragma once
// Cutter: progressive cuts of a TetMesh by a blade (docs/cut.md).
//
//   Cutter cutter(mesh);                      // options: CutOptions
//   cutter.start(blade_at_t0);
//   CutStepReport r = cutter.advance(blade_at_t1);   // cuts what the blade swept
//   sim.apply(r.change);                      // every backend updates locally
//
// One step, subdivision mode: find the tets the step's cut triangles touch (a walk from the
// previous step's tets; on first contact, a grid over rest positions kept up to date from the
// cuts' TopologyChanges, see cut/tet_grid.h: never a scan of the mesh), embed each triangle's boundary
// (its corners and edges become mesh vertices and edges: tet, face and edge splits), split
// every edge the triangle crosses, so the cut surface is a union of tet faces; then duplicate
// each cut-surface vertex once per connected component of its tet star across non-cut faces,
// tag the opened faces kTagCut, improve the touched tets locally, and hand out ONE
// TopologyChange. Sign decisions use exact predicates on the current positions; intersection
// points are floating point. A vertex within `snap` (relative to its mean edge) of a cut
// triangle's plane counts as lying on it (the cut surface bends through the vertex instead of
// making a sliver), and a blade-boundary point within `snap` of a tet edge or vertex is put on
// it. The blade front (where the blade stopped inside the body) stays attached: its vertices
// have one star component and are not duplicated.
//
// Removal mode (carving) deletes the tets the cut triangles touch and tags the exposed faces
// kTagCut: simpler, loses volume, kept for comparison.
//
// Current configuration: during a simulation pass `positions` (current position of any vertex
// that existed before the step). New vertices get rest AND current positions from the same
// barycentric weights, recorded in the TopologyChange, so the deformed shape does not jump.
// With positions, also pass `max_displacement`, a bound on |current - rest| over the vertices
// (a simulation has it from its displacement vector): first contact then looks only near the
// blade. Left unknown (negative), it is measured over the vertices, an O(V) pass.
//
// Edits made to the mesh outside this cutter (another cutter, improve(), fragment removal) are
// noticed by the mesh's edit counter: pass their TopologyChange to notify() to keep the grid
// exact in O(change), or the next first contact rebuilds it (O(mesh)).
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "cut/blade.h"
#include "cut/snap_rule.h"
#include "mesh/tet_mesh.h"
#include "quality/improve.h"

namespace incise {

enum class CutMode { Subdivide, Remove };

struct CutOptions {
  CutMode mode = CutMode::Subdivide;
  // Snap threshold relative to the local (mean incident) edge length: vertices closer
  // than this to a cut plane are treated as on it; a blade-boundary point within half of it
  // (relative to its element) of a point made in the same step goes onto that point (existing
  // vertices and edges take it only within the floor: the blade's boundary must stay a chain of
  // edges along its segment, CutStep::vertex_radius). Larger: fewer, better-shaped new tets,
  // cut surface further from the blade. A floor of 1e-6 always applies (points of earlier
  // splits are floating point).
  double snap = 0.05;
  bool improve = true;             // local flips + smoothing after each step
  // A progressive cut's sheet stays one plane while the blade stays within this distance of
  // it, relative to the mean edge of the tets the blade is in (its ends are projected onto the
  // plane): a curving path, or tissue moving under the blade, is cut as a few planar sheets
  // whose number follows the path's curvature and the mesh size, not the number of steps
  // (docs/cut.md#curved-paths). Past it a new sheet starts from the last front, once the blade
  // is an edge away from it. 0: a new sheet wherever the swept quad leaves the plane.
  double path_tolerance = 0.25;
  // true: a progressive cut given current positions that differ from the rest ones maps each
  // step's blade into the rest shape through the affine map that best fits the deformation of
  // the tets the blade is in, and cuts there: the sheet and its front are in material
  // coordinates and move with the tissue, instead of a world-space plane re-stitched into the
  // rest shape at every step (creases where the tissue moved). Off by default: where the tissue
  // bends under the blade the mapped path curves, and the sheets it takes cost quality
  // (docs/cut.md#moving-tissue).
  bool material_frame = false;
  // true: after each progressive step the tets the blade is in are cut provisionally against
  // the swept polygon, its front (the blade) embedded, so the cut is open up to the blade; the
  // next step (or finish()) takes those pieces back (TetMesh::undo) before it cuts, so the
  // committed cut is the same as without them. A step's TopologyChange then replaces the last
  // step's provisional pieces by the tets they came from and adds its own. Off by default: in a
  // simulation the pieces' flaps close and open again every frame, and the frame through a cut
  // costs more (docs/cut.md#the-opening).
  bool provisional = false;
  // true (the default): the cut and its improvement keep every label's volume, and the body's,
  // to rounding: a contraction that moves the body's surface (improve_options'
  // collapse_tolerance and collapse_deviation) is taken only with its kept vertex moved by what
  // gives the label its volume back, within the cut planes there
  // (ImproveOptions::collapse_restores_volume), and curved slides are off. The cut itself never
  // moves volume (snapping moves only interior vertices of one label). false takes those
  // contractions as they are, moving volume by a hair each, and lets vertices slide on curved
  // surfaces (docs/cut.md#label-volumes says what each way costs).
  bool exact_volumes = true;
  // Used when improve (rings, budget, ...); frozen is set per step. Contraction tolerance 0.01:
  // where the rim passes within a hair of a surface vertex, the edge between them may go even
  // on the curved surface (moving it by at most that hair, well inside the snap threshold).
  // Contraction deviation 0.05 (the default snap): short edges on bent cut sheets and along the
  // rim go too, the surface moving by at most what snapping moves it. With exact_volumes the
  // kept vertex then gives the label the volume back (see there).
  // One ring around the step's tets, not two: queueing two rings cost more than a small
  // budget before any operation, for about the same quality (docs/cut.md#the-defaults).
  // The budget counts operations (max_work: attempted flips, smoothings, contractions), not
  // time, so the same cut gives the same mesh on every run and machine.
  ImproveOptions improve_options = [] {
    ImproveOptions o;
    o.collapse_tolerance = 0.01;
    o.collapse_deviation = 0.05;
    o.rings = 1;
    o.max_work = kDefaultImproveWork;
    // Insertion only from the bad tet and its points, not into its edges' stars: placed in the
    // rest shape, a vertex in such a larger cavity inverts more tets of the deformed shape
    // (docs/improve.md, Insertion).
    o.edge_star_insertion = false;
    return o;
  }();
  // A few operations a step: a step that commits a layer of tets stays cheap, and the work
  // its tets need is spread over the next steps (cutter.cpp, improve queue; docs/cut.md#the-defaults).
  static constexpr int kDefaultImproveWork = 8;
  // Operations of finish()'s improvement (once per cut, so more): first the repair of every
  // tet the drag made that is still short of the steps' queue bounds, then the front released
  // and taken to the improvement's targets (docs/cut.md#curved-paths). An insertion attempt
  // counts 10 (ImproveOptions::insertion_work).
  int finish_improve_work = 5000;
  // finish()'s improvement also inserts vertices (quality/insertion.h) into tets whose smallest
  // dihedral stays below this many degrees after flips, contraction and smoothing (0: none).
  // Where a cut crosses earlier cuts or meets the surface at a small angle, the wedge between
  // the two sheets has no good tets at the old size: it needs smaller ones. Only the worst
  // tets, not every tet short of the targets: that grew the mesh far more for little gain
  // (docs/cut.md#the-defaults).
  double finish_insertion_below_deg = 15;
  // At most this many of them in finish() itself, the rest in later finish_more() calls (one
  // slice each: a simulation calls it once a frame, so the withdrawn blade's improvement is
  // spread over frames instead of stalling one; README, "When a blade is withdrawn"). 0: all
  // of it in finish().
  int finish_improve_slice = 0;
  // Optional wall-clock cap of the local improvement per step, on top of max_work; 0: none.
  // A time cap makes the result depend on the machine and its load.
  double improve_budget_ms = 0;
  std::vector<VertexId> frozen;    // vertices improvement must not move (e.g. constrained nodes)
  // Fragments: after a step, the tets on each side of the new cut faces are flood-filled
  // through face neighbours up to this many tets; a side that closes within it is reported
  // as a detached fragment. 0 disables the check.
  std::size_t fragment_search_limit = 20000;
};

// A connected part a cut detached (every tet reached, count <= fragment_search_limit).
struct Fragment {
  std::vector<TetId> tets;
  double volume = 0;
};

struct CutStepReport {
  TopologyChange change;              // edits of the step (cut + improvement), one record
  std::size_t tets_cut = 0;           // tets of the mesh before the step that the cut split or removed
  std::size_t tets_added = 0;         // change.added_tets.size()
  std::size_t vertices_added = 0;     // new vertices (split points and duplicates)
  std::size_t vertices_duplicated = 0;
  std::size_t cut_faces = 0;          // faces opened (each side counted once: pairs)
  std::size_t provisional_faces = 0;  // faces opened provisionally, taken back by the next step (not in cut_faces)
  // The last step's provisional pieces this one took back: the tets they came from, put back
  // (in change.added_tets), and the vertices they had made (in change.removed_vertices).
  std::size_t tets_taken_back = 0, vertices_taken_back = 0;
  double cut_area = 0;                // area of the cut, one side: subdivision's opened faces; removal's
                                      // half of what it exposed (the channel has two walls)
  double exposed_area = 0;            // area of all new boundary faces (subdivision: twice cut_area)
  std::vector<Fragment> fragments;    // parts detached by this step
  // When this step closed every part (a small body cut through): the one taken as the body,
  // the largest by volume, which `fragments` leaves out; empty otherwise. A caller whose
  // constraints hold a smaller part may find this one free (scene/scene_runner.cpp).
  Fragment body;
  double ms = 0;                      // wall time of the step (cut + improvement)
  double ms_improve = 0;
  ImproveReport improve;
};

class Cutter {
public:
  // positions(v): current position of vertex v (during a simulation); empty: rest positions.
  using PositionFn = std::function<Vec3(VertexId)>;

  static constexpr double kUnknownDisplacement = -1.0;
  // How far (in edges) a sheet may be grown in its plane at its end to place its front, the
  // next crease, out of the body or clear of the mesh's edges (place_front): where the fewest
  // edges pass closer than kCreaseClearance of an edge, if every edge clears it by
  // kCreaseClearanceMin.
  static constexpr double kFrontExitReach = 0.25;
  static constexpr double kCreaseClearance = 0.1;
  static constexpr double kCreaseClearanceMin = 0.05;
  // A curve sampled finely turns a little at every step and leaves the sheet's plane over
  // several; where the path turns at one point by enough that the next step leaves the
  // previous step's straight continuation by more than this share of path_tolerance, that
  // point is a corner: the sheet ends there instead of running straight across it and
  // cutting off the corner's triangle (docs/cut.md#curved-paths, *Corners*). Not with
  // CutOptions::material_frame, whose mapped path turns with the tissue.
  static constexpr double kCornerShare = 0.65;

  // Builds the first-contact grid over the mesh (O(mesh), once).
  explicit Cutter(TetMesh& mesh, CutOptions options = {});
  ~Cutter();
  Cutter(Cutter&&) noexcept;
  Cutter& operator=(Cutter&&) noexcept;

  // Positions the blade without cutting (a new cut). A cut not finish()ed is completed (its
  // waiting tets cut, without finish()'s improvement) by the next step, in that step's record.
  void start(const BladeSegment& blade);
  // Cuts what the blade sweeps moving from its last position to `blade` (InvalidArgument
  // before start() or after finish(): there is no last position). Subdivision mode cuts
  // progressively: steps in one plane grow one swept polygon (cut/sheet.h), and a tet is cut
  // against that polygon once the blade has left it (its section with the plane lies inside
  // the polygon, and the snap decisions of its vertices are final); the tets the blade is in
  // wait. finish() cuts those. So the result does not depend on how a motion is sliced into
  // steps, and the opening trails the blade by the tets it is in.
  CutStepReport advance(const BladeSegment& blade, const PositionFn& positions = {},
                        double max_displacement = kUnknownDisplacement);
  // Whether a blade is placed (start() called, finish() not since): advance() may be called.
  bool in_cut() const;
  // One-shot cuts: a plane through the whole mesh, or a triangulated surface.
  CutStepReport cut_plane(const Vec3& point, const Vec3& normal, const PositionFn& positions = {},
                          double max_displacement = kUnknownDisplacement);
  CutStepReport cut_surface(std::span<const CutTriangle> triangles, const PositionFn& positions = {},
                            double max_displacement = kUnknownDisplacement);
  // The blade is withdrawn (the cut ends here): the front need no longer stay where it is, so
  // the tets around it get the local improvement with its vertices free (a front step's
  // improvement keeps them frozen, and nothing else revisits them), and the front is
  // forgotten. One record, like a step's; empty when improvement is off or nothing was cut.
  // Call it when a cut ends; start() alone forgets the front without improving it.
  CutStepReport finish(const PositionFn& positions = {});
  // Whether finish()'s improvement has operations left (finish_improve_slice > 0).
  bool finishing() const;
  // The next slice of that improvement (finish_improve_slice operations at most) around the
  // withdrawn blade's front, its edits in one record; empty when nothing is left. It ends
  // when the operations are spent, the pass has converged or a slice changed nothing (the
  // next would repeat it); start() drops what is left.
  CutStepReport finish_more();
  // Edits of the mesh made elsewhere, taken by the first-contact grid in O(change).
  void notify(const TopologyChange& change);

  const CutOptions& options() const;
  CutOptions& options();
  const BladeSegment& blade() const;
  // Tets near the blade after the last step (where the next step's walk starts).
  const std::vector<TetId>& front_tets() const;
  // Tets the blade's current sheet crosses that are not cut yet (the blade is in them).
  std::size_t waiting_tets() const;

private:
  struct Impl;  // the cut's state and its steps (cut/cutter_impl.h, internal to cut/)
  std::unique_ptr<Impl> impl_;
};

}  // namespace incise
