#pragma once
// The measure mesh improvement maximizes: a tet's worst dihedral angle relative to the
// targets, q = min over its six dihedral angles theta of min(theta / lo, (180 - theta) /
// (180 - hi)) for targets lo (smallest wanted angle) and hi (largest). q >= 1 means the tet
// meets both targets; q is continuous, scale-free, and -1 for an inverted or flat tet.
// Operations compare configurations with better(): the worst q must rise, the minimum radius
// ratio may not drop below the floor (nor at all where it is already below), and the minimum
// (maximum) dihedral angle may not drop (rise) except within the targets.
#include <array>
#include <span>

#include "mesh/tet_mesh.h"

namespace incise {

struct AngleTargets {
  double min_deg = 35;   // smallest dihedral angle wanted
  double max_deg = 135;  // largest dihedral angle wanted
  // q does not see needles (one vertex far from a small triangle: fine dihedral angles, radius
  // ratio near 0), so an operation may not lower the radius ratio of the tets it replaces below
  // this floor (1: not at all). The improvement pass lowers it to
  // ImproveOptions::radius_ratio_floor when it inserts vertices (see there).
  double radius_ratio_floor = 1;
  // An operation may raise its tets' largest dihedral angle up to this, past max_deg and their
  // own largest (0: not at all): the global pass sets it to the mesh's largest when insertion
  // starts, so the mesh's largest angle never gets worse than it was then.
  double max_deg_cap = 0;
};

// Worst values over a set of tets (or one tet).
struct AngleQuality {
  double q = 1e300;         // worst measure (see above)
  double min_dihedral = 180;  // degrees
  double max_dihedral = 0;    // degrees
  double radius_ratio = 1;    // 3 r_in / R_circ (1 regular; guards against needles and caps)
  void combine(const AngleQuality& o);
};

AngleQuality angle_quality(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3, const AngleTargets& t);
// angle_quality(...).q alone (bit for bit the same value), without the radius ratio: for
// searches that compare q only (smoothing's ascent).
double angle_q(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3, const AngleTargets& t);
// angle_quality in two parts, each bit for bit the whole's: q and the dihedral angles (radius
// ratio left at 1), and the radius ratio alone (the same for any targets).
AngleQuality angle_quality_angles(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3,
                                  const AngleTargets& t);
double angle_radius_ratio(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3);
AngleQuality angle_quality(const TetMesh& mesh, TetId t, const AngleTargets& targets);
// Worst over tets given as vertex quadruples of `mesh`.
AngleQuality angle_quality(const TetMesh& mesh, std::span<const std::array<VertexId, 4>> tets,
                           const AngleTargets& targets);

// True when `after` replaces `before` with a strictly higher worst q (by more than a small
// margin, so repeated operations make real progress), a minimum radius ratio at least
// min(before's, targets.radius_ratio_floor), a minimum dihedral at least min(before's, targets.min_deg) and a maximum at most
// max(before's, targets.max_deg, targets.max_deg_cap).
bool better(const AngleQuality& after, const AngleQuality& before, const AngleTargets& targets);

}  // namespace incise
