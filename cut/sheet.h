#pragma once
// Internal to cut/: the surface one planar blade motion has swept so far. A progressive cut
// does not cut each step's thin swept quad into the mesh (that made the cut depend on how the
// motion was sliced into steps: a front embedded every step, snapping decided per sliver, and
// the mesh growing with the step count). Steps whose quads continue the same plane grow one
// convex polygon instead, and the mesh is cut against that polygon, the same one a single step
// over the whole motion would have swept.
//
// The polygon is a ring of points in the plane; the edge ring[front] -> ring[front + 1] is where
// the blade is now (from its b end to its a end). Collinear points along the sides are merged,
// so a straight sweep stays a quadrilateral whatever the number of steps.
#include <optional>
#include <vector>

#include "cut/blade.h"
#include "cut/cut_piece.h"

namespace incise::cut_detail {

class Sheet {
public:
  // The sheet one step starts: the quad the blade swept from `from` to `to` (one of its two
  // triangles may be degenerate), or nothing when the quad is not planar or folds over.
  // `tol` (a length): a to.a within it of the plane of (from.a, from.b, to.b) is projected
  // onto it (a blade that twisted a little), 0: planar to rounding only.
  static std::optional<Sheet> start(const BladeSegment& from, const BladeSegment& to, double tol = 0);
  // Grows the sheet by the quad swept from the current front to `to` when that quad lies in the
  // plane, faces the same way and keeps the polygon convex; false (sheet unchanged) otherwise.
  // `tol` (a length): blade ends within it of the plane count as in it and are projected onto
  // it, so a curving path (or tissue moving under the blade) continues the sheet while it
  // stays that close; the front is then the projected blade (front() != the blade).
  bool extend(const BladeSegment& to, double tol = 0);
  // How far the blade `b` is from the plane (its farther end).
  double deviation(const BladeSegment& b) const;
  // The polygon as a cut piece: fan triangles, every edge a boundary segment (the front marked),
  // the plane fixed at the first step's triangle.
  const Piece& piece() const { return piece_; }
  BladeSegment front() const;
  const Vec3& normal() const { return normal_; }
  // The back edge (where the sheet started) is a crease shared with an earlier sheet: not a rim.
  void set_back_is_crease(bool crease);

private:
  void rebuild_piece();
  bool convex() const;

  std::vector<Vec3> ring_;
  std::vector<bool> keep_;  // points never merged away (the back edge's ends)
  std::size_t front_ = 0;
  CutTriangle plane_;
  Vec3 normal_ = Vec3::Zero();
  double scale_ = 0;  // size of the first step's quad: tolerance reference
  double tol_ = 0;    // the last path tolerance (a length): sides bent this little count as straight
  bool back_crease_ = false;
  Piece piece_;
};

}  // namespace incise::cut_detail
