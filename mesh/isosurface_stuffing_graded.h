#pragma once
// Private to isosurface_stuffing.cpp: the octree-graded BCC lattice of the graded variant.
//
// Coordinates are the uniform lattice's doubled integer coordinates (finest cube c has corners
// 2c..2c+2 and centre 2c+1). The octree is balanced across faces and edges (neighbours that
// share a face or an edge differ by at most one level); its leaves are finest cubes wherever
// the star of a lattice vertex that the cut or warp steps can touch reaches, and coarsen away
// from the surface, inside and outside. Lattice tets fill the pyramid (leaf centre, leaf
// face) of every leaf face:
//  - same-size neighbour: the 4 BCC tets around the segment joining the two centres (emitted
//    once), each bisected at the midpoint of its face edge when a finer cell touches that edge;
//    finest ones are the uniform lattice's tets, ordered (centre, centre, corner, corner);
//  - coarser neighbour: the pyramid is split in two along the face diagonal through the
//    coarse face's centre ("half pyramids");
//  - finer neighbours: the face has a centre vertex; tets (centre, face centre, edge half), the
//    quadrisected BCC tets (bisected ones where a face edge has no midpoint cannot occur in a
//    balanced octree, every such face edge carries a finer cell's corner).
// Every face of that subdivision is shared by exactly the same triangle on both sides.
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

namespace incise::stuffing_detail {

using Key3 = std::array<std::int32_t, 3>;

struct GradedLatticeInput {
  std::array<int, 3> cells{};     // domain extent in finest cubes; the lattice may extend it
  double h = 0;                   // finest cube edge, for the distance bounds
  std::size_t max_tets = 0;       // refuse early when the estimate exceeds it
  std::function<double(const Key3&)> value;  // f at a lattice point (the caller caches)
  std::vector<Key3> forced;       // lattice points whose neighbourhood must be finest
  // Called with the estimated tet count when it exceeds max_tets; must throw.
  std::function<void(double)> refuse;
};

// Emits every lattice tet: emit(keys, fine), fine = a finest BCC tet (uniform lattice tet).
// The finest region covers the stars of the lattice vertices that end a sign-changing edge or
// where f = 0, for a 1-Lipschitz f; `forced` widens it where the caller found that false.
void graded_bcc_lattice(const GradedLatticeInput& in,
                        const std::function<void(const std::array<Key3, 4>&, bool)>& emit);

}  // namespace incise::stuffing_detail
