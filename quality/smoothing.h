#pragma once
// Optimization-based smoothing (Freitag and Ollivier-Gooch): move one vertex to raise the
// worst angle_quality() of its incident tets by nonsmooth steepest ascent (the direction is
// the smallest vector in the convex hull of the active tets' gradients; the step is halved
// until the worst value rises). Interior vertices move freely. A vertex on the boundary (or
// on the interface between two labels) moves within that surface when its faces there form
// one disc with one tag (one label pair): within its plane when the disc is flat, so the
// surface, each cut plane and each label's volume stay exactly; on a smooth curved disc (no
// edge sharper than feature_angle_deg; only with slide_curved, never for cut faces) it moves
// in the tangent plane and is projected back onto the old disc, so it stays on the old
// surface (the surface then changes by at most the disc's sagitta). A vertex on a straight
// crease (tags or planes change across two boundary edges in line) slides along it. Other
// vertices (corners, curved feature edges, where three labels meet) stay. The move goes through
// TetMesh::move_vertex, recorded as a point of the mesh before the move.
#include <cstdint>
#include <unordered_map>
#include <unordered_set>

#include "mesh/tet_mesh.h"
#include "quality/improve_scope.h"

namespace incise {

// How far slides on curved discs may move each label's volume: a slide that would take a
// label's net change past its limit is refused (flat slides keep volumes exactly).
struct VolumeAllowance {
  std::unordered_map<int, double> limit;  // per label, absolute volume
  std::unordered_map<int, double> moved;  // per label, net change by curved slides so far
};

struct SmoothOptions {
  bool move_surface = true;  // boundary (non-cut) vertices may slide in flat neighbourhoods
  bool move_cut = true;      // vertices on cut-tagged faces may slide in their plane
  bool move_interface = true;  // vertices on a two-label interface may slide within it
  bool slide_curved = false;   // also slide on smooth curved discs (surface changes slightly)
  double feature_angle_deg = 30;  // adjacent disc faces bent more than this: a feature (fixed)
  int iterations = 8;        // ascent steps
  const std::unordered_set<std::uint32_t>* frozen = nullptr;  // vertex ids that never move
  // Vertices that already slid on a curved disc in this pass: they slide there once, so the
  // drift from the input surface stays within one disc's sagitta (nullptr: no limit).
  std::unordered_set<std::uint32_t>* curved_slid = nullptr;
  VolumeAllowance* volume = nullptr;  // curved slides spend it (nullptr: no limit)
};

// Returns true when v moved (its tets strictly better by better()).
bool smooth_vertex(TetMesh& mesh, VertexId v, const ImproveScope& scope, const SmoothOptions& opt);

}  // namespace incise
