#pragma once
// Mesh improvement: topological flips (2-3, 3-2, 4-4, edge removal with the optimal ring
// triangulation, multi-face removal with the optimal disc, boundary edge removal between
// coplanar faces of one tag), contraction of short edges (quality/collapse.h),
// optimization-based vertex smoothing and optional vertex insertion, worst element first. The measure is
// angle_quality() (quality/dihedral_objective.h): the worst dihedral angle relative to the
// targets, so small and large angles both count. An operation is applied only when it raises
// the worst measure of the tets it replaces, keeps their minimum radius ratio (with insertion:
// above a floor, or where it was if lower), and lowers
// their minimum dihedral (raises their maximum) at most to the target: the worst element never
// gets worse and no tet inverts. Labels, boundary tags and the surface are kept (flips stay in
// one label; boundary and interface vertices slide only within flat, single-tag neighbourhoods
// unless slide_curved), so each label's volume is kept up to rounding.
#include <span>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise {

class AngleQualityCache;

struct ImproveOptions {
  double time_limit_s = 10;          // global mode wall-clock limit
  double time_budget_ms = 0;         // local mode budget (0 = unlimited apart from max_work)
  int max_work = 0;                  // cap on attempted operations (0 = none)
  double target_dihedral_deg = 35;   // stop improving a tet once its min dihedral reaches this
  double target_max_dihedral_deg = 135;  // ... and its max dihedral is at most this
  double radius_ratio_floor = 0.1;   // with insertion: an operation may lower its tets' min radius ratio,
                                     // but not below this (nor at all where it already is below), so the
                                     // mesh's never drops below min(input's, floor). The strict guard
                                     // refused most insertions that lift organ meshes; without insertion
                                     // it stays strict (the floor there cost quality; docs/improve.md#
                                     // behind-the-defaults). 1 = strict
  bool flips = true;                 // 2-3, 3-2, 4-4, edge removal and multi-face removal
  bool multi_face_removal = true;    // ... multi-face removal among them (quality/multi_face_removal.h)
  bool smoothing = true;             // optimization-based vertex smoothing
  bool insertion = false;            // vertex insertion into a cavity (quality/insertion.h) where the rest fails
  double insertion_below_deg = 0;    // ... only into tets whose smallest dihedral is below this (0: any tet short
                                     // of the targets): refinement where slivers are left, not everywhere
  int insertion_work = 10;           // ... an attempt counts as this many operations against max_work: it
                                     // costs about ten of the others (docs/improve.md#behind-the-defaults),
                                     // so a budget in operations stays one in time (a finish() slice per frame)
  int max_cavity = 16;               // ... largest cavity (tets replaced by one insertion)
  bool edge_star_insertion = true;   // ... also into the stars of the bad tet's edges (quality/insertion.h)
  bool boundary_insertion = true;    // ... also on boundary faces (split in their plane, tag kept), where
                                     // move_surface (move_cut for cut faces) allows boundary changes
  bool collapse = true;              // edge contraction of a tet's short edge (mesh/edge_collapse.h), also of
                                     // vertices added earlier in the batch (a cut's new vertices)
  double collapse_edge_ratio = 0.2;  // ... an edge shorter than this times the tet's longest
  double collapse_tolerance = 0;     // > 0: an edge at most this times the longest edge at the removed vertex
                                     // may contract where the boundary or a label interface is curved,
                                     // creased or a corner (moving it by that edge; volume_change says how
                                     // much). 0: the boundary and interfaces stay exactly (cutter: 0.01)
  double collapse_deviation = 0;     // > 0: a boundary or interface vertex may also be contracted along its
                                     // curved or bent surface (never across a feature edge: see
                                     // feature_angle_deg), when it stays within this times its mean surface
                                     // edge of the surface after (quality/collapse.h; cutter: 0.05, its snap)
  bool collapse_restores_volume = false;  // with collapse_tolerance or collapse_deviation: such a contraction
                                     // is taken only with the kept vertex moved by what gives the label its
                                     // volume back exactly (within the cut planes there; quality/collapse.h),
                                     // so labels keep their volumes to rounding (the cutter's exact_volumes)
  double max_growth = 1.5;           // tet count stays <= max_growth x input (region in local mode)
  bool move_surface = true;          // boundary vertices may slide within the (flat part of the) surface
  bool move_cut = true;              // vertices on cut-tagged faces may slide within their plane
                                     // (both on: boundary vertices may also be contracted away)
  bool move_interface = true;        // vertices on a flat two-label interface may slide within it
  bool slide_curved = false;         // boundary/interface vertices also slide on smooth curved parts (no edge
                                     // sharper than feature_angle_deg), staying on the old surface; the
                                     // surface and per-label volumes then change slightly (never cut faces)
  double volume_tolerance = 1e-4;    // with slide_curved: curved slides may move each label's volume by at most
                                     // this fraction of it (net; of the region's in local mode), the way
                                     // Stellar bounds surface smoothing. 1: no limit in practice
  double feature_angle_deg = 30;     // dihedral between boundary faces above which an edge is a feature
  int max_curved_slides = 3;         // with slide_curved: how often one vertex may slide on a curved disc or a
                                     // feature line in a pass (each time onto the faces it is on then)
  bool slide_feature_lines = true;   // with slide_curved: a vertex on exactly two feature edges (a line through
                                     // it, bent by at most feature_line_angle_deg) slides along the old line,
                                     // spending the volume allowance like a curved slide
  double feature_line_angle_deg = 60;  // ... how much such a line may bend at the vertex (degrees)
  bool reshape_surface = true;       // with slide_curved: boundary edge flips between faces of one tag that are
                                     // not coplanar (quality/boundary_flips.h), within the volume allowance,
                                     // when the old edge stays within surface_flip_deviation of the new one
  double surface_flip_deviation = 0.1;  // ... distance between the old and new edge, relative to the shorter
  std::span<const VertexId> frozen;  // vertices that must not move or be removed
  int rings = 2;                     // local mode: rings grown around the seeds
  int max_ring = 7;                  // edge removal: largest ring (tets around the edge) tried
  int smoothing_iterations = 8;      // ascent steps per vertex smoothing attempt
  // Local mode: figures of the region's tets kept from earlier passes (quality/quality_cache.h;
  // the cutter's steps); null: each pass evaluates its region.
  AngleQualityCache* quality_cache = nullptr;
};

struct ImproveReport {
  double min_dihedral_before = 0, max_dihedral_before = 0, min_dihedral_after = 0, max_dihedral_after = 0;
  double min_radius_ratio_before = 0, min_radius_ratio_after = 0;
  std::size_t tets_before = 0, tets_after = 0;
  int flips23 = 0, flips32 = 0, flips44 = 0, edge_removals = 0, multi_face_removals = 0, smoothing_moves = 0,
      insertions = 0, contractions = 0;
  int boundary_insertions = 0;  // insertions on a boundary face (counted in insertions too)  // contractions: edge collapses (one vertex removed each)
  int boundary_flips = 0;  // boundary edge removals between coplanar faces (2-2 and larger)
  double volume_change = 0;  // sum of |label volume change| of tolerance-mode contractions (else 0)
  // Largest change of one label's volume, relative to it (measured, all operations; over the
  // region in local mode): 0 up to rounding unless slide_curved or tolerance-mode contraction.
  double label_volume_change = 0;
  double seconds = 0;
  std::vector<VertexId> moved_vertices;  // vertices whose position changed (for local backend refresh)
  bool budget_exhausted = false;
  bool growth_capped = false;  // an insertion was refused because the tet count reached max_growth
  int surface_flips = 0;       // boundary flips between faces that are not coplanar (in boundary_flips too)
  int feature_slides = 0;      // smoothing moves along a bent feature line (in smoothing_moves too)
  int work = 0;                // operations spent, as counted against max_work
};

// Adds a later pass's report to an earlier one's over the same mesh: counts and work summed,
// "before" figures kept, "after" figures and budget state the later pass's.
void accumulate(ImproveReport& into, const ImproveReport& next);

// Whole mesh, worst elements first, within opt.time_limit_s. All edits go through the mesh's
// check-then-act API and accumulate in the mesh's pending TopologyChange (one change per pass).
ImproveReport improve(TetMesh& mesh, const ImproveOptions& opt = {});
// Seeds plus opt.rings rings around them only; bounded by opt.time_budget_ms / opt.max_work.
// Never does O(mesh) work. In local mode the min/max "before/after" figures are over the region.
ImproveReport improve_local(TetMesh& mesh, std::span<const TetId> seeds, const ImproveOptions& opt = {});

}  // namespace incise
