#pragma once
// PointLocator: which tet of a mesh holds a point, and where in it (barycentric coordinates),
// for comparing fields on different meshes of one body (incise trade reads a reference
// solution at another mesh's vertices). A uniform grid over the rest positions lists the tets
// whose bounding box meets each cell; a query tests the tets of the point's cell and, for a
// point outside the mesh (a coarser mesh's vertex off a curved surface), searches outward for
// the nearest tet and clamps onto it.
#include <array>
#include <cstdint>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise {

struct PointLocation {
  TetId tet;                     // invalid only for an empty mesh
  std::array<double, 4> weights; // barycentric, >= 0, sum 1: the point (or its clamp onto the tet)
  double distance = 0;           // from the point to that location: 0 inside the mesh
};

// The point of triangle abc nearest to p (any triangle, flat ones too).
Vec3 closest_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

// p in the tet of v's star where it lies deepest: that tet's vertices and p's barycentric
// weights in it (move_vertex's parents), and the smallest weight, negative when p lies outside
// the star. No tet: -infinity and the vectors untouched.
double star_coordinates(const TetMesh& mesh, VertexId v, const Vec3& p, std::vector<VertexId>& parents,
                        std::vector<double>& weights);

class PointLocator {
public:
  explicit PointLocator(const TetMesh& mesh);  // O(mesh); the mesh must outlive it
  PointLocation locate(const Vec3& p) const;
  // sum_k weights[k] * field(vertex k) for a field of `width` values per vertex slot.
  static void interpolate(const TetMesh& mesh, const PointLocation& at, const double* field, int width, double* out);

private:
  std::array<std::int64_t, 3> cell_of(const Vec3& p) const;
  void try_cell(std::int64_t i, std::int64_t j, std::int64_t k, const Vec3& p, PointLocation& best) const;

  const TetMesh* mesh_;
  Vec3 origin_ = Vec3::Zero();
  double cell_ = 1;
  std::array<std::int64_t, 3> dims_{1, 1, 1};
  std::vector<std::uint32_t> start_, tets_;  // CSR: cell c lists tets_[start_[c] .. start_[c + 1])
};

}  // namespace incise
