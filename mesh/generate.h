#pragma once
// Structured tetrahedral meshes for tests, benchmarks and users.
#include <array>

#include "mesh/tet_mesh.h"

namespace incise {

// How make_box splits each cube into 6 tets. Kuhn: around the main diagonal, every cube alike.
// Mirrored: the same split reflected along each axis where the cube's index is odd, so the
// diagonals alternate (face diagonals still match: conforming). Standard tets lock far less
// on the mirrored pattern (docs/solver.md#formulations-which-to-pick-formulation-in-scenes,
// bench_fem_locking --split mirrored).
enum class BoxSplit { Kuhn, Mirrored };

// Box [0,size.x] x [0,size.y] x [0,size.z] with cells.x*cells.y*cells.z cubes, each split
// into 6 tets (`split`; conforming across cubes). Boundary faces are
// tagged kTagSurface; every tet gets `label`. Throws InvalidArgument for sizes <= 0 or cell
// counts < 1.
TetMesh make_box(const Vec3& size, const std::array<int, 3>& cells, int label = 1, BoxSplit split = BoxSplit::Kuhn);

// Ellipsoid centred at the origin with semi-axes `radii`: a box of (2n)^3 cubes on
// [-1,1]^3 mapped radially onto the unit ball, then scaled. n >= 1.
TetMesh make_ellipsoid(const Vec3& radii, int n, int label = 1);

// Sector of a thick-walled tube around the z axis: radii [inner, outer], polar angle
// [0, angle_deg] from the x axis, z in [0, height]; cells = (radial, around, along) cubes of the
// (r, theta, z) lattice, mapped to Cartesian (the map keeps orientation). The wall faces are
// tagged so that loads can select them: r = inner kTagTubeInner, r = outer kTagTubeOuter, the
// rest (end caps, the sector's flat sides) kTagSurface. A quarter tube (angle 90) with rollers
// on its flat sides and end caps is the plane-strain Lame cylinder of elasticity texts.
// 0 < inner < outer, 0 < angle_deg < 360, height > 0, every count >= 1.
constexpr std::uint16_t kTagTubeInner = 16, kTagTubeOuter = 17;
TetMesh make_tube(double inner, double outer, double height, double angle_deg, const std::array<int, 3>& cells,
                  int label = 1);

// Cook's membrane (Cook 1974), the plane benchmark for distorted meshes and near-incompressibility:
// the trapezoid (0,0), (48,44), (48,60), (0,44) in x-y, extruded to z in [0, thickness] as one
// layer. cells x cells quads, each column x = const mapped linearly from the bottom edge
// (y = 44 x / 48) to the top edge (y = 44 + 16 x / 48), times one layer, each hexahedron split
// into 6 tets. The clamped edge x = 0 is tagged kTagCookClamped, the loaded edge x = 48
// kTagCookLoaded, the rest kTagSurface. Plane strain: hold z on every vertex. cells >= 1,
// thickness > 0.
constexpr std::uint16_t kTagCookClamped = 18, kTagCookLoaded = 19;
TetMesh make_cook_membrane(int cells, double thickness = 1, int label = 1);

// Tags every boundary face kTagSurface (used by generators and readers).
void tag_boundary(TetMesh& mesh, std::uint16_t tag = kTagSurface);

}  // namespace incise
