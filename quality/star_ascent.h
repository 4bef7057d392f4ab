#pragma once
// The optimization behind smoothing and insertion: a vertex's star with the vertex's slot
// open, and nonsmooth steepest ascent of the star's worst angle_quality() over the vertex's
// position (Freitag and Ollivier-Gooch): the direction is the smallest vector in the convex
// hull of the active tets' gradients, the step is halved until the worst value rises.
#include <array>
#include <functional>
#include <vector>

#include "quality/dihedral_objective.h"

namespace incise {

struct OpenStar {
  std::vector<std::array<Vec3, 4>> tets;
  std::vector<int> slot;  // the open vertex's local index in each tet
  AngleQuality at(const Vec3& p, const AngleTargets& t) const;
  AngleQuality one(std::size_t i, const Vec3& p, const AngleTargets& t) const;
  // q alone (the same value as one(i, p, t).q, without the radius ratio).
  double one_q(std::size_t i, const Vec3& p, const AngleTargets& t) const;
  // one(i, p, t) in its two parts (angle_quality_angles, angle_radius_ratio): the same values.
  AngleQuality one_angles(std::size_t i, const Vec3& p, const AngleTargets& t) const;
  double one_radius_ratio(std::size_t i, const Vec3& p) const;
};

struct AscentOptions {
  int iterations = 8;     // ascent steps
  double scale = 1;       // local length (shortest edge at the vertex): steps and differences scale with it
  const Vec3* normal = nullptr;  // move only perpendicular to this (a plane or a tangent plane)
  const Vec3* line = nullptr;    // move only along this (a crease)
  // Maps a wanted position to one the vertex can take (e.g. back onto a surface); false: none.
  std::function<bool(Vec3&)> project;
};

// The best position found from p0 whose star is better() than at p0, or p0 itself.
// `at_p0`, `at_best`: where to put star.at(p0, targets) and star.at(result, targets) (the
// search computes both anyway).
Vec3 ascend(const OpenStar& star, const Vec3& p0, const AngleTargets& targets, const AscentOptions& opt,
            AngleQuality* at_p0 = nullptr, AngleQuality* at_best = nullptr);

}  // namespace incise
