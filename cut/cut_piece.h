#pragma once
// Internal to cut/: one planar piece of a step's cut surface and the geometric tests the
// cutter makes against it. A piece is a planar region given as triangles sharing one plane
// (a swept quad whose blade did not rotate out of plane is one piece of two triangles), and the
// segments bounding it (the ones that must become mesh edges).
#include <array>
#include <span>
#include <vector>

#include "cut/blade.h"

namespace incise::cut_detail {

struct Piece {
  std::vector<CutTriangle> triangles;            // all in the plane of `plane`
  CutTriangle plane;                              // exact reference of the plane (sides)
  std::vector<std::array<Vec3, 2>> boundary;      // segments to embed
  std::vector<bool> rim;                          // per segment: an edge of the whole cut so far
                                                  // (not shared with another piece or step)
  Vec3 normal = Vec3::Zero();                     // unit normal of the plane
  // Exact side of x: the sign of orient3d over `plane`.
  int side(const Vec3& x) const;
  // Floating signed distance of x to the plane.
  double distance(const Vec3& x) const { return normal.dot(x - plane.p[0]); }
  // Whether x (near the plane) projects inside one of the triangles, with a tolerance
  // relative to the triangle's size.
  bool contains(const Vec3& x, double rel_tol) const;
  // Distance from x to the nearest rim segment.
  double boundary_distance(const Vec3& x) const;
  Vec3 lo, hi;  // bounding box
};

// Groups a step's triangles into pieces: consecutive triangles that share an edge and are
// coplanar (within a relative 1e-9) merge, and their shared edge is not a boundary.
std::vector<Piece> make_pieces(std::span<const CutTriangle> triangles);
// Sets the plane, normal and box from the triangles (plane: triangles[0]) and every boundary
// segment a rim.
void finish_piece(Piece& p);
// Marks segment (a,b) (either direction) as not a rim in every piece.
void mark_inner_segment(std::vector<Piece>& pieces, const Vec3& a, const Vec3& b);

// Barycentric coordinates of x in triangle (a,b,c) (x assumed near its plane).
std::array<double, 3> triangle_barycentric(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& x);

// Conservative overlap test of a tet and a triangle: false only when a separating plane
// (a tet face, the triangle's plane or an axis-aligned box side) separates them by more than
// tol.
bool tet_may_touch_triangle(const std::array<Vec3, 4>& tet, const CutTriangle& tri, double tol);

}  // namespace incise::cut_detail
