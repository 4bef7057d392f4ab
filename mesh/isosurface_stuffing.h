#pragma once
// Isosurface stuffing (Labelle & Shewchuk, "Isosurface Stuffing: Fast Tetrahedral Meshes with
// Good Dihedral Angles", SIGGRAPH 2007): fills the region {sdf < 0} with tetrahedra cut from a
// body-centred cubic (BCC) lattice of spacing h.
//
// Contract
//  - Sign convention: sdf(p) < 0 inside, > 0 outside; the surface is sdf = 0.
//  - sdf must be 1-Lipschitz, |sdf(p)| <= distance from p to the surface (a true or a clamped
//    signed distance, e.g. an OpenVDB narrow-band level set): blocks of 8^3 cells whose
//    centre value exceeds their radius (+2h) are skipped unsampled, so a true distance costs
//    O(cells near or inside the object) however large the box. A level set clamped to a
//    narrow band prunes only blocks smaller than the band: keep the box tight then. Values
//    larger than the distance may lose parts of the object.
//  - The object should lie inside [lo, hi] with a margin of a cell or more; what sticks out
//    of the box is clipped by it (the mesh is then the object intersected with the box).
//  - Dihedral angles: with the default alpha_long = 0.24999, alpha_short = 0.41189 the
//    paper proves (computer-assisted) every output tet has dihedral angles in
//    [10.7 deg, 164.8 deg], for any isosurface. Other alphas in (0, 0.5) give valid,
//    conforming meshes without that guarantee.
//  - Single-threaded; sdf is called about once per lattice point near or inside the object
//    plus ~5-10 times per surface-crossing lattice edge (bracketed root finding).
//  - Boundary vertices lie on the isosurface (cut points found by bracketed root finding on
//    sdf along lattice edges, or lattice vertices warped onto them). Whether the boundary is
//    a manifold with the surface's topology depends on h resolving the surface's features.
//  - Output: positively oriented tets labelled options.label, boundary faces tagged
//    kTagSurface, no pending TopologyChange.
//  - Graded (options.graded): the lattice comes from an octree balanced 2:1 across faces and
//    edges. Its leaves are cubes of edge h over the whole star of every lattice vertex the
//    cut and warp steps can touch (f = 0 there, or it ends a sign-changing edge) and double
//    in size away from the surface, inside and outside; bisected and quadrisected BCC tets
//    and half pyramids join cells of different sizes. Cut, warp (same alphas) and stencils
//    are the uniform ones. The rule is checked at run time (and the octree refined until it
//    holds, which only an sdf off the contract needs), so every tet the stencils change sees
//    exactly the uniform lattice around it and the uniform [10.7, 164.8] deg argument applies
//    to it; every other output tet is an unchanged lattice tet (45 to 120 deg). That rule is
//    stricter than the paper's graded octree, whose own graded alphas and bounds are not
//    reproduced here (the angles measured on random shapes: docs/tetra.md#graded-stuffing).
//    Near the surface the lattice is the uniform one, so boundary and volume match the uniform
//    mesh's (up to the warping order); the interior costs O(area / h^2) tets and sdf calls
//    instead of O(volume / h^3). A level set saturating
//    within ~3h of its surface makes the graded build sample every lattice point (in blocks
//    whose value is below the saturation), as the uniform build does.
// Throws InvalidArgument for bad options, a box that is empty or not finite, a sdf returning
// NaN, an empty result (sdf >= 0 at every lattice point), or an estimated size above
// max_tets (the message gives the estimate).
#include <cstddef>
#include <functional>

#include "mesh/tet_mesh.h"

namespace incise {

struct StuffingOptions {
  double cell_size = 0;        // BCC lattice spacing h: cube edge (long edges); required, > 0
  bool graded = false;         // octree-graded lattice: finest (h) near the surface only
  double alpha_long = 0.24999; // warp threshold on long (same-grid) edges, fraction of length
  double alpha_short = 0.41189;// warp threshold on short (cross-grid) edges, fraction of length
  int label = 1;               // region label of every output tet
  std::size_t max_tets = 50'000'000;  // refuse (with an estimate) beyond this many tets
};

// Dihedral angle bounds (degrees) the paper guarantees for the default alphas (graded: see
// the contract above).
inline constexpr double kStuffingMinDihedral = 10.7;
inline constexpr double kStuffingMaxDihedral = 164.8;

TetMesh isosurface_stuffing(const std::function<double(const Vec3&)>& sdf, const Vec3& lo, const Vec3& hi,
                            const StuffingOptions& options);

}  // namespace incise
