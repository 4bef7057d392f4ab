// incise convert IN OUT: between tet mesh formats (labels and boundary tags travel where the
// format carries them), tet mesh -> its boundary surface, surface -> surface. Atomic output.
// --spatial-order renumbers a tet mesh along a space-filling curve (TetMesh::compact_spatially).
#include <iostream>

#include "cli/commands.h"
#include "mesh/errors.h"
#include "mesh/io/atomic_file.h"
#include "mesh/io/surface.h"
#include "mesh/io/tet_io.h"

namespace incise::cli {

void add_convert(CLI::App& app) {
  struct Opts {
    std::string in, out;
    bool binary = false, big_endian = false, header64 = false, no_boundary = false, spatial_order = false;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("convert", "Convert between mesh formats (by extension)");
  cmd->add_option("input", o->in, "Input: tet mesh (.msh .mesh .vtk .vtu .node/.ele) or surface")->required();
  cmd->add_option("output", o->out,
                  "Output: tet mesh (.msh = gmsh 2.2, .mesh, .vtk, .vtu, .node/.ele) or surface (.off .obj .stl: "
                  "the boundary of a tet mesh)")
      ->required();
  cmd->add_flag("--binary", o->binary, "Binary payload (.vtk, .vtu)");
  cmd->add_flag("--big-endian", o->big_endian, "Big-endian binary payload (.vtu; implies --binary)");
  cmd->add_flag("--header64", o->header64, "UInt64 block headers (.vtu binary)");
  cmd->add_flag("--no-boundary", o->no_boundary, "Do not write tagged boundary triangles (.msh, .mesh)");
  cmd->add_flag("--spatial-order", o->spatial_order,
                "Renumber vertices and tets along a space-filling curve (tet mesh output): simulations run faster "
                "on meshes whose numbering is scattered in space (incise tetra already writes this order)");
  cmd->callback([o] {
    const bool in_tet = is_tet_mesh_path(o->in), out_tet = is_tet_mesh_path(o->out);
    // An option the output format has no use for is refused, not ignored: the user asked for
    // something the file will not have.
    const TetFormat f = format_from_path(o->out);
    auto refuse = [&](bool given, const char* option, bool applies, const char* where) {
      if (given && !applies)
        throw InvalidArgument("convert: " + std::string(option) + " applies to " + where + " output only, not " + o->out);
    };
    refuse(o->binary, "--binary", f == TetFormat::VtkLegacy || f == TetFormat::Vtu, ".vtk and .vtu");
    refuse(o->big_endian, "--big-endian", f == TetFormat::Vtu, ".vtu");
    refuse(o->header64, "--header64", f == TetFormat::Vtu && (o->binary || o->big_endian),
           "binary .vtu (with --binary or --big-endian)");
    refuse(o->no_boundary, "--no-boundary", f == TetFormat::Gmsh22 || f == TetFormat::Medit, ".msh and .mesh");
    refuse(o->spatial_order, "--spatial-order", out_tet, "tet mesh");
    OutputTransaction tx;  // the output is checked before reading; a .node/.ele pair is written whole
    if (out_tet)
      reserve_tet_mesh_output(tx, o->out);
    else
      tx.reserve(o->out, "the output");
    if (in_tet) forbid_tet_mesh_input(tx, o->in);
    else tx.forbid_input(o->in);
    if (in_tet) {
      ReadReport report;
      TetMesh m = read_tet_mesh(o->in, &report);
      if (o->spatial_order) m.compact_spatially();
      if (out_tet) {
        WriteOptions w;
        w.binary = o->binary || o->big_endian;
        w.big_endian = o->big_endian;
        w.header_uint64 = o->header64;
        w.write_boundary = !o->no_boundary;
        write_tet_mesh(m, o->out, w, tx);
        tx.commit();
        std::cerr << "convert: " << o->in << " (" << report.format << ") -> " << o->out << ": " << m.num_vertices()
                  << " vertices, " << m.num_tets() << " tets\n";
      } else {
        SurfaceMesh s = boundary_surface(m);
        write_surface(s, o->out);
        std::cerr << "convert: boundary of " << o->in << " -> " << o->out << ": " << s.vertices.size() << " vertices, "
                  << s.triangles.size() << " triangles\n";
      }
    } else {
      if (out_tet)
        throw InvalidArgument(o->in + ": a surface cannot be converted to a tetrahedral mesh; tetrahedralize it first");
      SurfaceMesh s = read_surface(o->in);
      write_surface(s, o->out);
      std::cerr << "convert: " << o->in << " -> " << o->out << ": " << s.vertices.size() << " vertices, "
                << s.triangles.size() << " triangles\n";
    }
  });
}

}  // namespace incise::cli
