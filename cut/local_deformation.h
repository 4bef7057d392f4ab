#pragma once
// Internal to cut/: the affine map x = A X + t that best fits (least squares) how a region of the
// mesh moved from its rest positions X to its current positions x. A progressive cut through
// moving tissue maps each step's blade into the rest shape with it, so that the cut's sheet and
// its front live in material coordinates and move with the tissue (docs/cut.md#moving-tissue).
#include <functional>
#include <optional>
#include <span>

#include "cut/blade.h"
#include "mesh/tet_mesh.h"

namespace incise::cut_detail {

struct LocalDeformation {
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();
  Vec3 t = Vec3::Zero();
  Vec3 to_rest(const Vec3& x) const { return A.inverse() * (x - t); }
  BladeSegment to_rest(const BladeSegment& b) const { return {to_rest(b.a), to_rest(b.b)}; }
};

// The fit over the vertices of `tets` (O(their number)); nothing when every one of them is at its
// rest position (still tissue: the blade needs no mapping) or there are none. Where the vertices
// do not span 3D, or the fitted map is near singular or inverts, a translation alone.
std::optional<LocalDeformation> fit_local_deformation(const TetMesh& mesh, std::span<const TetId> tets,
                                                      const std::function<Vec3(VertexId)>& positions);

}  // namespace incise::cut_detail
