#pragma once
// A signed distance field of a surface on a narrow-band OpenVDB grid (the grid stays in
// level_set.cpp). It is the repair path for dirty surfaces and the input of the stuffing
// engine.
//
// Building it: the inside is whatever cannot be reached from outside the bounding box
// without crossing the surface, so self-intersections, non-manifold edges, several shells
// and inverted faces all resolve to "the union of what the surface encloses". Holes are
// closed by a morphological closing of radius `closing_radius` (dilate by r through the
// unsigned distance, flood-fill the outside, erode by r): holes narrower than 2r close,
// concave gaps narrower than 2r fill as well. With closing_radius 0 the sign comes from
// OpenVDB's own flood fill (a hole wider than a voxel would leak, so callers pass r > 0
// for open input).
#include <memory>

#include "mesh/io/surface.h"
#include "mesh/tetrahedralize/surface_check.h"
#include "mesh/tetrahedralize/tetrahedralize.h"

namespace incise {

struct LevelSetOptions {
  Length voxel{0.005, true};   // voxel size: diagonal / 200
  double closing_radius = -1;  // absolute; < 0: automatic (largest hole radius + 2 voxels, 0 if closed)
  double interior_band = -1;   // absolute distance kept exact inside; 0: 3 voxels; < 0: whole interior
  double exterior_band = -1;   // absolute distance kept exact outside; < 0: 3 voxels
};

class SignedDistance {
public:
  // Throws InvalidArgument for an empty surface or a grid that would exceed ~2^31 voxels.
  SignedDistance(const SurfaceMesh& surface, const LevelSetOptions& options = {});
  ~SignedDistance();
  SignedDistance(SignedDistance&&) noexcept;
  SignedDistance& operator=(SignedDistance&&) noexcept;

  // Trilinear interpolation; negative inside. Far from the surface the value saturates at
  // the band width. Thread-safe.
  double operator()(const Vec3& p) const;
  // The zero isosurface (closed, manifold, outward), triangulated.
  SurfaceMesh zero_surface() const;
  Vec3 lo() const;  // bounding box of the field (surface bbox plus a margin)
  Vec3 hi() const;
  double voxel() const;
  double closing_radius() const;  // resolved value

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct RepairReport {
  double voxel = 0;
  double closing_radius = 0;
  std::size_t input_triangles = 0;
  std::size_t output_triangles = 0;
  SurfaceDistance distance;  // repaired vs input, sampled
  std::string summary() const;
};

// Rebuilds `surface` as the zero set of its level set (see SignedDistance) and measures
// how far the result moved from the input.
SurfaceMesh repair_surface(const SurfaceMesh& surface, const LevelSetOptions& options = {},
                           RepairReport* report = nullptr);

}  // namespace incise
