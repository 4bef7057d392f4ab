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
#include <chrono>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <unordered_map>
#include <span>
#include <vector>

#include "cut/blade.h"
#include "cut/local_deformation.h"
#include "cut/snap_rule.h"
#include "cut/tet_grid.h"
#include "mesh/tet_mesh.h"
#include "quality/improve.h"

namespace incise {

namespace cut_detail {
class CutStep;
struct Piece;
struct CutFacePair;
struct SeparationResult;
struct FragmentScratch;
}  // namespace cut_detail

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
  // to rounding: the improvement's contractions may not move the body's surface, a cut or a
  // label interface (improve_options' collapse_tolerance and collapse_deviation, and curved
  // slides, are off). The cut itself never moves those (snapping moves only interior vertices
  // of one label). false lets those contractions remove slivers along curved rims and bent
  // sheets, moving volume by a hair each (docs/cut.md#label-volumes says what each way costs).
  bool exact_volumes = true;
  // Used when improve (rings, budget, ...); frozen is set per step. With exact_volumes off,
  // contraction tolerance 0.01:
  // where the rim passes within a hair of a surface vertex, the edge between them may go even
  // on the curved surface (moving it by at most that hair, well inside the snap threshold).
  // Contraction deviation 0.05 (the default snap): short edges on bent cut sheets and along the
  // rim go too, the surface moving by at most what snapping moves it.
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
  bool in_cut() const { return started_; }
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
  bool finishing() const { return finish_left_ > 0; }
  // The next slice of that improvement (finish_improve_slice operations at most) around the
  // withdrawn blade's front, its edits in one record; empty when nothing is left. It ends
  // when the operations are spent, the pass has converged or a slice changed nothing (the
  // next would repeat it); start() drops what is left.
  CutStepReport finish_more();
  // Edits of the mesh made elsewhere, taken by the first-contact grid in O(change).
  void notify(const TopologyChange& change);

  const CutOptions& options() const { return opt_; }
  CutOptions& options() { return opt_; }
  const BladeSegment& blade() const { return blade_; }
  // Tets near the blade after the last step (where the next step's walk starts).
  const std::vector<TetId>& front_tets() const { return front_; }
  // Tets the blade's current sheet crosses that are not cut yet (the blade is in them).
  std::size_t waiting_tets() const;

private:
  struct Progress;  // the sheet being swept and its waiting tets (cutter.cpp)
  // The caller's positions, plus the vertices this call made (cleared at each public call).
  PositionFn with_fresh(const PositionFn& positions);
  void remember_fresh(const cut_detail::CutStep& step, const cut_detail::SeparationResult& sep,
                      const PositionFn& positions);
  std::unordered_map<std::uint32_t, Vec3> fresh_;
  // Separates the step's cut faces and adds what it did to the report.
  cut_detail::SeparationResult open_faces(const cut_detail::CutStep& step, std::span<const cut_detail::CutFacePair> faces,
                                          CutStepReport& rep, const PositionFn& positions, bool split_chords = true);
  // The step's tets and its embedded front segment are where the next step continues.
  void set_front(const cut_detail::CutStep& step, const BladeSegment& front);
  // Progressive subdivision step from `from` to `to` (advance).
  CutStepReport sweep(const BladeSegment& from, const BladeSegment& to, const PositionFn& positions,
                      double max_displacement);
  // Cuts what the current sheet still has waiting, embedding its boundary; forgets the sheet.
  // next_follows: the blade turned and the next sheet starts at this one's front (a crease).
  void finish_sheet(CutStepReport& rep, const PositionFn& positions, bool next_follows = false);
  // sweep()'s parts (cut/cutter.cpp): a non-planar quad cut in full, a step of the current sheet,
  // and the sheet's lists after the step's improvement.
  // The walk over the step's quad starts from `from` (the last front) and goes on from those
  // of `then` (the tets the grid says the quad may touch) it did not reach.
  struct Walk {
    std::span<const TetId> from, then;
  };
  void cut_quad(CutStepReport& rep, const cut_detail::Piece& local, const std::function<std::vector<TetId>()>& scan,
                const Walk& walk, const PositionFn& positions, const BladeSegment& to, std::vector<TetId>& seeds,
                std::vector<VertexId>& frozen);
  void step_sheet(CutStepReport& rep, const cut_detail::Piece& local, const std::function<std::vector<TetId>()>& scan,
                  const Walk& walk, const PositionFn& positions, std::vector<TetId>& seeds, std::vector<VertexId>& frozen);
  void keep_sheet_lists(const PositionFn& positions);
  // A new sheet from `from` (a finished sheet's front, or the blade's last position) to `to`.
  void start_sheet(const BladeSegment& from, const BladeSegment& to, const PositionFn& positions);
  // Cut faces an earlier sheet's finish left shut (their opening would have pinched the
  // boundary until the next sheet opened its side): offered again at every later finish of a
  // sheet, as corner triples (the tets around them may have been replaced since).
  std::vector<std::array<VertexId, 3>> shut_faces_;
  void keep_shut_faces(std::span<const cut_detail::CutFacePair> shut);
  void revive_shut(std::vector<cut_detail::CutFacePair>& faces);
  void open_stale(CutStepReport& rep, const PositionFn& positions);  // the shut faces alone
  // Moving tissue (CutOptions::material_frame): the map of this cut's blade into the rest shape
  // (set once the tissue under the blade is seen to have moved; the cut is then made in the rest
  // shape to its finish) and where the last step put the blade there.
  std::optional<cut_detail::LocalDeformation> map_;
  BladeSegment rest_blade_;
  bool rest_known_ = false;
  std::optional<cut_detail::LocalDeformation> local_deformation(const BladeSegment& from, const BladeSegment& to,
                                                                const PositionFn& positions, double max_displacement);
  // A curved path's next sheet, from the last front to the blade, when one is due (finish()).
  void resume_to_blade(const PositionFn& positions, const BladeSegment& blade);
  // Mean edge length of (a sample of) the tets the blade is in; 0 when it is in none.
  double local_edge(const PositionFn& positions) const;
  // The cut faces at the crease this sheet started from (CutStep::crease_faces), added to
  // `faces`: those neither sheet's own test finds.
  void add_crease_faces(const cut_detail::CutStep& step, std::vector<cut_detail::CutFacePair>& faces) const;
  // Local improvement of the region just cut; the waiting tets' vertices stay put.
  void improve_after(CutStepReport& rep, std::vector<TetId> seeds, std::vector<VertexId> frozen);
  // A cut start() left unfinished is completed before the next edit (cut/cutter.cpp).
  void complete_previous(CutStepReport& rep, const PositionFn& positions);
  bool needs_improving(TetId t) const;  // joins the per-step improvement queue
  void keep_made(Progress& pr) const;  // adds the pending change's tets to pr.made
  // Keeps the live tets with a face in the sheet's plane still shut (and adds their partner).
  void keep_shut(std::vector<TetId>& tets) const;
  void refresh_waiting(const PositionFn& positions, std::span<const TetId> more);
  CutStepReport run(std::span<const CutTriangle> triangles, const PositionFn& positions, double max_displacement,
                    bool use_front);
  // run()'s two modes (the tets the pieces touch removed, or split and opened) and the
  // improvement around a subdivided step's front; `scan` finds the first contact.
  using ContactFn = std::function<std::vector<TetId>()>;
  void carve_pieces(std::span<const cut_detail::Piece> pieces, std::span<const TetId> seeds, const ContactFn& scan,
                    const PositionFn& positions, CutStepReport& rep);
  void subdivide_pieces(std::span<const cut_detail::Piece> pieces, std::vector<TetId> seeds, const ContactFn& scan,
                        const PositionFn& positions, bool use_front, CutStepReport& rep);
  void improve_around_front(CutStepReport& rep);
  // Tets the grid says a step's quad may touch (its triangles cut into boxes of a few cells).
  std::vector<TetId> quad_contact(const cut_detail::Piece& local, const PositionFn& positions, double max_displacement);
  // Whether p lies in a live tet (current positions; the grid must be up to date).
  bool in_body(const Vec3& p, const PositionFn& positions, double max_displacement);
  // At a sheet's end: grows it in its plane (up to kFrontExitReach of an edge) so that its
  // front, the next crease, is out of the body or clear of the mesh's edges (the .cpp).
  void place_front(const BladeSegment& to, const PositionFn& positions, double max_displacement);
  // How clear the segment [a, b] is of the edges of the tets near it (edges it passes through
  // exactly, and edges in the plane with this normal, do not count): the smallest distance, and
  // how many edges are closer than kCreaseClearance * reach.
  struct Clearance {
    double nearest = std::numeric_limits<double>::infinity();
    std::size_t near_edges = 0;
  };
  Clearance clearance(const Vec3& a, const Vec3& b, const Vec3& normal, double reach, const PositionFn& positions,
                      double max_displacement);
  // Tets that may touch the pieces' box in the current configuration (first contact).
  std::vector<TetId> first_contact(const Vec3& lo, const Vec3& hi, const PositionFn& positions,
                                   double max_displacement, bool grid_stale);

  TetMesh* mesh_;
  CutOptions opt_;
  BladeSegment blade_;
  bool started_ = false;
  std::vector<TetId> front_;
  BladeSegment front_segment_;          // where the last step's blade stopped ...
  std::vector<VertexId> front_vertices_;  // ... and the mesh vertices along it
  bool has_front_ = false;
  std::unique_ptr<Progress> progress_;
  // The provisional pieces of the last step (CutOptions::provisional): how to take them back,
  // and, should the mesh be edited elsewhere before that (no undo then), the front they embedded.
  struct ProvisionalCut {
    TetMesh::UndoLog log;
    BladeSegment front;
    std::vector<VertexId> front_vertices;
    std::vector<TetId> tets;
  };
  std::optional<ProvisionalCut> provisional_;
  void cut_provisional(CutStepReport& rep, const PositionFn& positions);
  void take_back_provisional(CutStepReport& rep);
  TetGrid grid_;
  std::uint64_t grid_edits_ = 0;  // the mesh's edit counter when the grid was last in sync
  std::unique_ptr<cut_detail::FragmentScratch> fragment_scratch_;  // the fragment search's marks
  // Tets beside the faces this call opened: where detached parts are looked for, once the
  // call's edits are done (find_detached).
  std::vector<TetId> fragment_starts_;
  // The call's improvement replaces tets (flips, contraction, insertion), a detached part's
  // too: its tets are collected after it, from the live starts and every tet the call added
  // (so a caller removing or fixing the part gets its current tets). After take_change().
  void find_detached(CutStepReport& rep);
  void find_detached(CutStepReport& rep, std::span<const TetId> added);  // before take_change()
  // finish()'s improvement still to come (finish_more): its region and operations left.
  std::vector<TetId> finish_seeds_;
  // Its first phase, the repair: the tets the drag made that are short of the step queue's
  // bounds (with the region's), to those bounds only; empty once done.
  std::vector<TetId> repair_seeds_;
  int finish_left_ = 0;
  // One slice of the finish improvement on finish_seeds_ (improvement only: no cut).
  void improve_finish_slice(CutStepReport& rep, int work);
  void keep_finish_seeds(const TopologyChange& change);  // the slice's new tets join the region
  void end_finish_record(CutStepReport& rep, bool grid_stale, std::chrono::steady_clock::time_point t0);
  // The call's edits taken into rep.change and its counts; the grid follows them unless it was
  // stale before the call (the next first contact rebuilds it).
  void take_record(CutStepReport& rep, bool grid_stale);
};

}  // namespace incise
