#pragma once
// Reading and writing tetrahedral meshes. The format is chosen by extension and checked
// against the content:
//   .msh        Gmsh 2.2 ASCII (read/write), 4.1 ASCII (read), 1.0 (read)
//   .mesh       Medit (read/write)
//   .vtk        VTK legacy 4.2 / 5.1, ASCII or binary (read/write 4.2)
//   .vtu        VTK XML UnstructuredGrid, ascii or base64 binary (inline or appended,
//               UInt32/UInt64 headers, either byte order, zlib-compressed read) (read/write)
//   .node/.ele  TetGen (read/write; either name may be given)
// Region labels travel through every format that carries them (msh physical tag, medit ref,
// vtk/vtu cell data "label" -- also read as "gmsh:physical", "CellEntityIds", "medit:ref" --,
// TetGen region attribute). Non-tet cells are skipped and counted, unreferenced vertices
// kept. Quadratic tets are read as their four corners. Tets are reoriented to positive volume
// on read; overlapping tets are refused (ReadOptions). Every boundary face is tagged
// kTagSurface, or with the tag of a boundary triangle the file carries (msh, medit); VTU and
// VTK, which have no triangles, carry the cut faces (kTagCut) as a cell array
// "cut_face_mask" that the writers add and the readers turn back into tags (TetGen: a second
// .ele attribute that the header comment names). Positions are
// written in shortest round-trip form, so they
// read back bit-exact. Every write is atomic (temporary file in the same directory, then
// rename); a failed write leaves the destination untouched.
#include <string>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise {

class OutputTransaction;  // mesh/io/atomic_file.h

enum class TetFormat { Auto, Gmsh22, Medit, VtkLegacy, Vtu, TetGen };

// Extra data written beside the mesh (VTU and VTK legacy only): simulation frames write
// current positions, displacement per point and stress per cell this way.
struct Field {
  std::string name;
  int components = 1;          // 1 (scalar) or 3 (vector)
  std::vector<double> values;  // point data: components * vertex_capacity(), indexed by VertexId
                               // cell data: components * tet_capacity(), indexed by TetId
};
struct MeshFields {
  const std::vector<Vec3>* points = nullptr;  // positions to write instead of rest (by VertexId)
  std::vector<Field> point_data;
  std::vector<Field> cell_data;
  // Quadratic cells (VTU only, VTK_QUADRATIC_TETRA = 24): per TetId its six mid-edge nodes in
  // VTK's order ((0,1), (1,2), (0,2), (0,3), (1,3), (2,3)) as indices into mid_points, which the
  // file lists after the vertices. Point data then holds components * (vertex_capacity() +
  // mid_points->size()) values: the vertices by VertexId, then the mid points.
  const std::vector<Vec3>* mid_points = nullptr;
  const std::vector<std::array<std::uint32_t, 6>>* mid_nodes = nullptr;
};

struct ReadReport {
  std::size_t skipped_cells = 0;         // triangles, lines, points beside the tets
  std::size_t reoriented_tets = 0;       // tets read with negative volume and flipped
  std::size_t unreferenced_vertices = 0;
  std::size_t degenerate_tets = 0;       // zero volume, kept as read
  std::size_t tagged_boundary_faces = 0; // boundary faces that got a tag from the file
  std::string format;                    // e.g. "gmsh 4.1 ascii"
  // VTU, VTK: the one-component cell arrays besides the label (a simulation frame's von_mises,
  // cut_faces, ...), by TetId. A "cut_face_mask" array (bit f: local face f is an opened cut
  // face, as incise's writers add it to every mesh with cut faces) also tags those boundary
  // faces kTagCut.
  std::vector<Field> cell_data;
};

struct ReadOptions {
  // Refuse a mesh two of whose tets overlap (mesh/overlap.h): O(T log T), in parallel. Never
  // applied to a deformed shape (a VTU / VTK file with a 3-component point array named
  // "displacement", as simulation frames have), where the sides of a cut may be pressed into
  // each other.
  bool refuse_overlaps = true;
};

struct WriteOptions {
  TetFormat format = TetFormat::Auto;  // Auto: from the extension
  bool binary = false;                 // VTK legacy / VTU: binary (VTU: base64 raw)
  bool big_endian = false;             // VTU binary: byte order of the payload
  bool header_uint64 = false;          // VTU binary: UInt64 block headers (else UInt32)
  bool write_boundary = true;          // also write boundary triangles with their tags,
                                       // where the format carries them (msh, mesh)
};


// Throws IoError("FILE:LINE: reason") on malformed input.
TetMesh read_tet_mesh(const std::string& path, ReadReport* report = nullptr);
TetMesh read_tet_mesh(const std::string& path, const ReadOptions& options, ReadReport* report = nullptr);
void write_tet_mesh(const TetMesh& mesh, const std::string& path, const WriteOptions& options = {});
// The same, staged in a command's transaction (written by tx.commit(), with its other outputs).
void write_tet_mesh(const TetMesh& mesh, const std::string& path, const WriteOptions& options, OutputTransaction& tx);
// Reserves in `tx` the files a mesh written to `path` consists of (base.node and base.ele for
// TetGen), before any work: throws IoError for an unknown extension or an unwritable path.
void reserve_tet_mesh_output(OutputTransaction& tx, const std::string& path, const std::string& role = "the output mesh");
// Every file the input path `path` names (a TetGen pair: both) is an input no output may be.
void forbid_tet_mesh_input(OutputTransaction& tx, const std::string& path);
// VTU (or VTK legacy, by extension) with current positions and fields; atomic.
void write_tet_mesh_with_fields(const TetMesh& mesh, const std::string& path, const MeshFields& fields,
                                const WriteOptions& options = {});

// The format an extension maps to (Auto if unknown).
TetFormat format_from_path(const std::string& path);
// Whether a path names a tet-mesh format (as opposed to a surface).
bool is_tet_mesh_path(const std::string& path);

}  // namespace incise
