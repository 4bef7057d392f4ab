#pragma once
// The Cutter's progressive state, shared by cutter.cpp (the steps) and cutter_finish.cpp
// (withdrawing the blade): internal to cut/, not part of the API.
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "cut/cut_step.h"
#include "cut/cutter.h"
#include "cut/sheet.h"

namespace incise {

// The progressive state of a subdivision cut (see advance()).
struct Cutter::Progress {
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
    std::unordered_map<std::uint32_t, int> sides;
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
