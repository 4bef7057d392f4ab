#pragma once
// Internal to mesh/io: what each format reader produces and each writer consumes. Readers
// only parse (checking every index and count against the file); build_mesh() turns the raw
// arrays into a TetMesh in one O(N) pass (orientation, boundary tags, report).
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "mesh/io/atomic_file.h"
#include "mesh/io/tet_io.h"

namespace incise::io {

struct RawMesh {
  std::vector<Vec3> points;
  std::vector<std::array<std::uint32_t, 4>> tets;  // indices into points
  std::vector<int> tet_labels;
  std::vector<long> tet_lines;                     // source line of each tet (0: unknown)
  std::string tet_file;                            // file the tets came from (TetGen: .ele)
  std::vector<std::array<std::uint32_t, 3>> tris;  // boundary triangles with tags (msh, medit)
  std::vector<int> tri_tags;
  std::size_t skipped_cells = 0;
  std::string format;
  // Scalar cell arrays beside the label (VTU), one value per tet in `tets` order.
  std::vector<std::pair<std::string, std::vector<double>>> cell_scalars;
  // The points are a deformed shape: the file carries a 3-component point array named
  // "displacement" (incise's simulation frames, Python write() with one).
  bool deformed = false;
};

// Parses `text` (the content of `file`); throws IoError on anything malformed.
// Lower-case extension without the dot ("" if none).
std::string lower_extension(const std::string& path);
// How good a name is for the label array of a VTK / VTU file, best first (0: not a label).
int label_rank(std::string_view name);

RawMesh parse_gmsh(const std::string& file, const std::string& text);
RawMesh parse_medit(const std::string& file, const std::string& text);
RawMesh parse_vtk_legacy(const std::string& file, const std::string& text);
RawMesh parse_vtu(const std::string& file, const std::string& text);
RawMesh parse_tetgen(const std::string& node_file, const std::string& node_text, const std::string& ele_file,
                     const std::string& ele_text);

TetMesh build_mesh(RawMesh&& raw, const std::string& file, ReadReport* report, const ReadOptions& options = {});

// The live part of a mesh, densely renumbered, for writers.
struct FlatMesh {
  std::vector<Vec3> points;
  std::vector<std::array<std::uint32_t, 4>> tets;
  std::vector<int> labels;
  std::vector<std::array<std::uint32_t, 3>> faces;  // boundary, outward
  std::vector<std::uint16_t> face_tags;
  std::vector<std::uint32_t> vertex_ids;  // dense index -> VertexId
  std::vector<std::uint32_t> tet_ids;     // dense index -> TetId
  std::vector<std::array<std::uint32_t, 6>> mid;  // quadratic cells: per tet its mid-edge points (empty: linear)
  // Fields gathered to dense order (components * count values each).
  struct DenseField {
    std::string name;
    int components = 1;
    std::vector<double> values;
  };
  std::vector<DenseField> point_data;
  std::vector<DenseField> cell_data;
};

void write_gmsh22(const FlatMesh& m, AtomicFile& out, const WriteOptions& options);
void write_medit(const FlatMesh& m, AtomicFile& out, const WriteOptions& options);
void write_vtk_legacy(const FlatMesh& m, AtomicFile& out, const WriteOptions& options);
void write_vtu(const FlatMesh& m, AtomicFile& out, const WriteOptions& options);
void write_tetgen(const FlatMesh& m, AtomicFile& node, AtomicFile& ele, const WriteOptions& options);

}  // namespace incise::io
