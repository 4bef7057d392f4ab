#pragma once
// Internal to cut/: specks. Where a sheet ends inside the body its front becomes a crease the
// next sheet starts from. The two sheets meet there at an angle, and with the snapping of
// vertices onto each sheet a tet or two in the narrow wedge between them can end up with every
// face on one sheet, the other or the surface: opened, they would fall off as a crumb of
// tissue the blade never cut out. Two sheets that meet along a crease enclose no tissue, so a
// closed group of a few tets at a crease is such a speck, never a piece the blade meant; it
// stays attached to the tissue beyond its largest face (that face stays shut).
#include <span>
#include <vector>

#include "cut/cut_step.h"
#include "mesh/tet_mesh.h"

namespace incise::cut_detail {

// At most this many tets make a speck; a closed group any larger is a part the cut made.
inline constexpr std::size_t kSpeckTets = 6;

// Drops from `faces` (the pairs about to be opened) the largest face of each speck: a group of
// at most kSpeckTets tets, holding a vertex of `crease`, that opening `faces` would close off
// from the rest of the mesh. Returns how many specks stay attached. Local: walks at most
// kSpeckTets tets from each face (and reads the crease once).
std::size_t keep_specks_attached(const TetMesh& mesh, std::vector<CutFacePair>& faces, std::span<const VertexId> crease);

}  // namespace incise::cut_detail
