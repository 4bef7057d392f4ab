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
// crease (tags or planes change across two boundary edges in line) slides along it; one on
// the front of a cut where it bends within the cut's plane (its faces folded onto each other,
// all in one plane) slides along the old front, onto one of its two segments; one on a
// bent feature line (exactly two feature edges, with slide_curved and feature_line_angle_deg)
// slides along the old line, onto one of its two old segments. Other vertices (corners, where
// three labels meet) stay. The move goes through
// TetMesh::move_vertex, recorded as a point of the mesh before the move.
#include <cstdint>
#include <unordered_map>
#include <unordered_set>

#include "mesh/id_set.h"
#include "mesh/tet_mesh.h"
#include "quality/improve_scope.h"
#include "quality/volume_allowance.h"

namespace incise {

struct SmoothOptions {
  bool move_surface = true;  // boundary (non-cut) vertices may slide in flat neighbourhoods
  bool move_cut = true;      // vertices on cut-tagged faces may slide in their plane
  bool move_interface = true;  // vertices on a two-label interface may slide within it
  bool slide_curved = false;   // also slide on smooth curved discs (surface changes slightly)
  double feature_angle_deg = 30;  // adjacent disc faces bent more than this: a feature
  // With slide_curved: a vertex on exactly two feature edges whose line bends at most this
  // (degrees) slides along the old line (the feature stays on its old polyline); 0: never.
  double feature_line_angle_deg = 0;
  int iterations = 8;        // ascent steps
  const IdSet* frozen = nullptr;  // vertex ids that never move
  // How often each vertex slid on a curved disc or a bent feature line in this pass: it slides
  // there at most max_curved_slides times, each onto the faces it is on, so its drift from the
  // input surface stays within that many discs' sagittas (nullptr: no limit).
  IdMap<int>* curved_slides = nullptr;
  int max_curved_slides = 1;
  VolumeAllowance* volume = nullptr;  // curved slides spend it (nullptr: no limit)
};

// How a vertex moved (None: it did not; its tets strictly better by better() otherwise).
enum class SmoothMove { None, Free, Plane, Surface, Crease, FeatureLine, Front };

SmoothMove smooth_vertex_how(TetMesh& mesh, VertexId v, const ImproveScope& scope, const SmoothOptions& opt);
// Returns true when v moved.
inline bool smooth_vertex(TetMesh& mesh, VertexId v, const ImproveScope& scope, const SmoothOptions& opt) {
  return smooth_vertex_how(mesh, v, scope, opt) != SmoothMove::None;
}

}  // namespace incise
