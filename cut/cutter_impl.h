#pragma once
// The Cutter's state and its steps (Cutter::Impl) and its progressive state (Progress),
// shared by cutter.cpp and cutter_finish.cpp: internal to cut/, not part of the API.
#include <chrono>
#include <limits>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "cut/cut_step.h"
#include "cut/cutter.h"
#include "cut/fragments.h"
#include "cut/local_deformation.h"
#include "cut/separate.h"
#include "cut/sheet.h"
#include "cut/tet_grid.h"
#include "quality/quality_cache.h"

namespace incise {

// The Cutter's state and its steps, shared by cutter.cpp (the steps) and cutter_finish.cpp
// (withdrawing the blade): internal to cut/, not part of the API. Cutter's public operations
// forward here (cutter.cpp).
struct Cutter::Impl {
  using PositionFn = Cutter::PositionFn;
  static constexpr double kFrontExitReach = Cutter::kFrontExitReach;
  static constexpr double kCreaseClearance = Cutter::kCreaseClearance;
  static constexpr double kCreaseClearanceMin = Cutter::kCreaseClearanceMin;
  static constexpr double kCornerShare = Cutter::kCornerShare;

  Impl(TetMesh& mesh, CutOptions options);
  // Cutter's operations (cutter.h says what each does).
  void start(const BladeSegment& blade);
  CutStepReport advance(const BladeSegment& blade, const PositionFn& positions, double max_displacement);
  CutStepReport cut_plane(const Vec3& point, const Vec3& normal, const PositionFn& positions, double max_displacement);
  CutStepReport cut_surface(std::span<const CutTriangle> triangles, const PositionFn& positions, double max_displacement);
  CutStepReport finish(const PositionFn& positions);
  CutStepReport finish_more();
  void notify(const TopologyChange& change);
  std::size_t waiting_tets() const;

  struct Progress;  // the sheet being swept and its waiting tets (below)
  // The caller's positions, plus the vertices this call made (cleared at each public call).
  PositionFn with_fresh(const PositionFn& positions);
  void remember_fresh(const cut_detail::CutStep& step, const cut_detail::SeparationResult& sep,
                      const PositionFn& positions);
  IdMap<Vec3> fresh_;
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
  // The waiting tets a step of the sheet may cut: not those behind its back edge when that edge
  // is a crease (see there).
  std::vector<TetId> waiting_ahead(const PositionFn& positions) const;
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
  // The waiting list again, with `more` offered too; recheck false: the live tets on it stay
  // without a look (nothing they depend on changed since the last refresh).
  void refresh_waiting(const PositionFn& positions, std::span<const TetId> more, bool recheck = true);
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
  // The steps' improvement passes share their tets' figures (consecutive regions overlap).
  AngleQualityCache step_quality_;
  // One slice of the finish improvement on finish_seeds_ (improvement only: no cut).
  void improve_finish_slice(CutStepReport& rep, int work);
  void keep_finish_seeds(const TopologyChange& change);  // the slice's new tets join the region
  void end_finish_record(CutStepReport& rep, bool grid_stale, std::chrono::steady_clock::time_point t0);
  // The call's edits taken into rep.change and its counts; the grid follows them unless it was
  // stale before the call (the next first contact rebuilds it).
  void take_record(CutStepReport& rep, bool grid_stale);
};

// The progressive state of a subdivision cut (see advance()).
struct Cutter::Impl::Progress {
  std::optional<cut_detail::Sheet> sheet;  // the polygon swept in the current plane
  cut_detail::CutMemory memory;  // its vertices' decided sides
  // Tets crossing the sheet that are not cut yet (the blade is in them, or their vertices'
  // snap decisions wait for it to pass), and tets beside cut faces that stayed closed (their
  // opening would have pinched the boundary): every step offers them again.
  std::vector<TetId> waiting, closed;
  // The sheet's back edge when an earlier sheet's front made it a chain of mesh edges.
  bool back_known = false;
  BladeSegment back;
  std::vector<VertexId> back_vertices;
  bool edited = false;  // this cut changed the mesh (finish() improves only then)
  // Curved paths (CutOptions::path_tolerance): the distance the sheet's plane may be from the
  // blade, and how far the blade must be from a finished sheet's front before the next sheet
  // starts there (both lengths, set from the local edge; 0 before the blade met the body).
  double tol = 0, reach = 0;
  // A sheet ended because the blade left its plane; the next starts from its front, `resume`,
  // once the blade is `reach` away from it (a quad from a front the blade has just left would
  // point across the path, not along it).
  std::optional<BladeSegment> resume;
  BladeSegment last_blade;  // where an unfinished cut's blade was when start() began the next
  std::optional<BladeSegment> step_from;  // where the last step began (the turn at a corner)
  // start() was called with a sheet unfinished: the next step (or finish) completes it first,
  // in the same record (start() itself hands out no change).
  bool complete_first = false;
  // Tets a step cut, with the step that cut them: each step improves them (and what this step
  // cut) within its operation budget, worst first, so the work a commit needs is spread over
  // the steps after it instead of falling on the one frame; a tet leaves after kImproveSteps.
  std::vector<std::pair<TetId, int>> improve_queue;
  // Tets the committed steps made (some dead since): finish() seeds those still short of the
  // queue's bounds. The steps' improvement reaches only the queue and holds the waiting tets'
  // vertices, and tets left behind (the creases of a curved path) are never revisited
  // (docs/cut.md#curved-paths).
  std::vector<TetId> made;
  std::size_t made_compacted = 0;
  int step = 0;
  // The sheet finished last when the blade turned, while the next one (starting at its front,
  // the crease) is cut: its polygon and its vertices' decided sides (CutStep::crease_faces).
  struct PreviousSheet {
    cut_detail::Piece piece;
    IdMap<int> sides;
    std::vector<VertexId> crease;  // the vertices along the crease, and their copies since
  };
  std::optional<PreviousSheet> previous;
};

namespace cut_detail {
inline constexpr int kImproveSteps = 4;
// Only tets this bad join the queue (their rings come with them): evaluating every tet a step
// cut, and its ring, at every step cost more than the operations (docs/cut.md#the-defaults).
// The finish() pass takes the rest to the improvement's own targets.
inline constexpr double kQueueMinDihedral = 20, kQueueMaxDihedral = 150;
}  // namespace cut_detail

}  // namespace incise
