#pragma once
// Cutter: progressive cuts of a TetMesh by a blade (DESIGN.md 2.5).
//
//   Cutter cutter(mesh);                      // options: CutOptions
//   cutter.start(blade_at_t0);
//   CutStepReport r = cutter.advance(blade_at_t1);   // cuts what the blade swept
//   sim.apply(r.change);                      // every backend updates locally
//
// One step, subdivision mode: find the tets the step's cut triangles touch (a walk from the
// previous step's tets; a spatial index only on first contact), embed each triangle's boundary
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
#include <chrono>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "cut/blade.h"
#include "mesh/tet_mesh.h"
#include "quality/improve.h"

namespace incise {

enum class CutMode { Subdivide, Remove };

struct CutOptions {
  CutMode mode = CutMode::Subdivide;
  // Snap threshold relative to the local (mean incident) edge length: vertices closer
  // than this to a cut plane are treated as on it; blade-boundary points this close to an edge
  // or vertex go onto it. Larger: fewer, better-shaped new tets, cut surface further from the
  // blade. A floor of 1e-6 always applies (points of earlier splits are floating point).
  double snap = 0.05;
  bool improve = true;             // local flips + smoothing after each step
  ImproveOptions improve_options;  // used when improve (rings, budget, ...); frozen is set per step
  double improve_budget_ms = 2.0;  // wall-clock budget of the local improvement per step
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
  double cut_area = 0;                // area of the opened faces (one side)
  std::vector<Fragment> fragments;    // parts detached by this step
  double ms = 0;                      // wall time of the step (cut + improvement)
  double ms_improve = 0;
  ImproveReport improve;
};

class Cutter {
public:
  // positions(v): current position of vertex v (during a simulation); empty: rest positions.
  using PositionFn = std::function<Vec3(VertexId)>;

  explicit Cutter(TetMesh& mesh, CutOptions options = {});

  // Positions the blade without cutting (a new cut: forgets the previous front).
  void start(const BladeSegment& blade);
  // Cuts what the blade sweeps moving from its last position to `blade`.
  CutStepReport advance(const BladeSegment& blade, const PositionFn& positions = {});
  // One-shot cuts: a plane through the whole mesh, or a triangulated surface.
  CutStepReport cut_plane(const Vec3& point, const Vec3& normal, const PositionFn& positions = {});
  CutStepReport cut_surface(std::span<const CutTriangle> triangles, const PositionFn& positions = {});

  const CutOptions& options() const { return opt_; }
  CutOptions& options() { return opt_; }
  const BladeSegment& blade() const { return blade_; }
  // Tets near the blade after the last step (where the next step's walk starts).
  const std::vector<TetId>& front_tets() const { return front_; }

private:
  CutStepReport run(std::span<const CutTriangle> triangles, const PositionFn& positions, bool use_front);

  TetMesh* mesh_;
  CutOptions opt_;
  BladeSegment blade_;
  bool started_ = false;
  std::vector<TetId> front_;
  BladeSegment front_segment_;          // where the last step's blade stopped ...
  std::vector<VertexId> front_vertices_;  // ... and the mesh vertices along it
  bool has_front_ = false;
};

}  // namespace incise
