#pragma once
// Triangle surfaces: what tetrahedralization starts from.
#include <array>
#include <string>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise {

struct SurfaceMesh {
  std::vector<Vec3> vertices;                 // #V
  std::vector<std::array<int, 3>> triangles;  // #F by 3, indices into vertices
};

// Reads any surface format assimp reads (OBJ, STL ascii/binary, PLY, glTF, ...) and OFF (read
// by incise itself: assimp's importer clamped bad indices and crashed on malformed files).
// Polygons are fan-triangulated, node transforms applied, points and lines dropped;
// vertices are kept as the importer gives them (not welded; STL has one per corner).
// Throws IoError naming the file for unreadable input or a file without triangles.
SurfaceMesh read_surface(const std::string& path);

// Writes OFF, OBJ, or STL (ASCII) chosen by extension; atomic.
void write_surface(const SurfaceMesh& surface, const std::string& path);

// The boundary of a tet mesh as a surface (vertices compacted, outward orientation).
SurfaceMesh boundary_surface(const TetMesh& mesh);

}  // namespace incise
