#pragma once
// Edge removal (Shewchuk, "Two discrete optimization algorithms for the topological
// improvement of tetrahedral meshes"): the tets around an interior edge (a,b) with ring
// c_0..c_{n-1} are replaced by the tets (c_i,c_j,c_k,b) and (c_i,c_k,c_j,a) of a
// triangulation of the ring polygon. The dynamic program over sub-polygons finds the
// triangulation that maximizes the worst angle_quality() in O(n^3).
#include <array>
#include <span>
#include <vector>

#include "quality/dihedral_objective.h"

namespace incise {

struct RingTriangulation {
  std::vector<std::array<int, 3>> triangles;  // ring indices, i < j < k, as TetMesh::remove_edge takes them
  AngleQuality worst;                        // worst over the 2(n-2) tets
};

// Tets of the triangle (i, j, k) (i < j < k) as TetMesh::remove_edge builds them.
std::array<std::array<Vec3, 4>, 2> ring_triangle_tets(std::span<const Vec3> ring, const Vec3& a, const Vec3& b,
                                                      int i, int j, int k);
// The best triangulation of the ring (n >= 3) for edge (a,b). With `floor`, the caller
// wants it only if its worst q is above the floor: the search skips what cannot end above it,
// and returns the same triangulation when the best one is above, and otherwise a worst q at
// most the floor (triangles then empty or partial: not to be used).
RingTriangulation best_ring_triangulation(std::span<const Vec3> ring, const Vec3& a, const Vec3& b,
                                          const AngleTargets& targets, double floor = -1e300);

}  // namespace incise
