// incise coarsen IN -o OUT: a coarser copy of a tet mesh (about twice the edge length, 1/4 ..
// 1/8 of the tets) by edge contraction then improvement; labels, boundary tags and the body's
// surface (within --max-deviation) kept. incise trade uses the same function for the coarser
// resolution of a scene whose mesh is a file.
#include <cstdio>
#include <iostream>

#include "cli/checks.h"
#include "cli/commands.h"
#include "mesh/io/atomic_file.h"
#include "mesh/io/tet_io.h"
#include "quality/coarsen.h"
#include "quality/metrics.h"

namespace incise::cli {

void add_coarsen(CLI::App& app) {
  struct Opts {
    std::string in, out;
    CoarsenOptions coarsen;
    bool no_improve = false;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("coarsen", "A coarser copy of a tet mesh by edge contraction (labels, tags and the surface kept)");
  cmd->add_option("input", o->in, "Tet mesh (.msh .mesh .vtk .vtu .node/.ele)")->required();
  cmd->add_option("-o,--output", o->out, "Coarser mesh (format by extension)")->required();
  cmd->add_option("--edge-factor", o->coarsen.edge_factor, "Target edge length as a multiple of the input's mean edge")
      ->check(finite_range(1, 100))
      ->capture_default_str();
  cmd->add_option("--max-deviation", o->coarsen.max_deviation,
                  "How far the surface may move (mesh units)")
      ->check(finite_range(0, 1e300, "0: a tenth of the target edge"))
      ->capture_default_str();
  cmd->add_option("--feature-angle", o->coarsen.feature_angle_deg,
                  "Surface edges bent more than this (degrees) are features: contracted only along themselves")
      ->check(finite_range(0, 180))
      ->capture_default_str();
  cmd->add_flag("--no-improve", o->no_improve, "Skip the improvement pass (flips, smoothing) after contracting");
  cmd->callback([o] {
    CoarsenOptions opt = o->coarsen;
    opt.improve = !o->no_improve;
    OutputTransaction tx;
    reserve_tet_mesh_output(tx, o->out);
    forbid_tet_mesh_input(tx, o->in);
    ReadReport read;
    TetMesh mesh = read_tet_mesh(o->in, &read);
    const double volume = mesh.total_volume();
    const CoarsenReport r = coarsen(mesh, opt);
    mesh.discard_change();
    mesh.compact();
    write_tet_mesh(mesh, o->out, {}, tx);
    tx.commit();
    const QualityRange q = quality_range(mesh);
    char buf[600];
    std::snprintf(buf, sizeof buf,
                  "%s (%s) -> %s\n"
                  "  tets      %zu -> %zu (%.3f), vertices %zu -> %zu\n"
                  "  mean edge %.4g -> %.4g (target %.4g), surface within %.4g\n"
                  "  volume    %.6g -> %.6g (%+.3g%%)\n"
                  "  dihedral  %.2f .. %.2f deg, min radius ratio %.3f (%d contractions, then %d flips, %d smoothing moves)\n",
                  o->in.c_str(), read.format.c_str(), o->out.c_str(), r.tets_before, r.tets_after,
                  double(r.tets_after) / double(std::max<std::size_t>(1, r.tets_before)), r.vertices_before,
                  r.vertices_after, r.mean_edge_before, r.mean_edge_after, r.target_edge, r.max_deviation, volume,
                  mesh.total_volume(), 100 * (mesh.total_volume() - volume) / volume, q.min_dihedral, q.max_dihedral,
                  q.min_radius_ratio, r.contractions,
                  r.improve.flips23 + r.improve.flips32 + r.improve.flips44 + r.improve.edge_removals +
                      r.improve.multi_face_removals + r.improve.boundary_flips,
                  r.improve.smoothing_moves);
    std::cout << buf;
  });
}

}  // namespace incise::cli
