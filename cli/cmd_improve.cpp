// incise improve IN -o OUT: flips and smoothing until the worst elements meet the targets or
// the time limit; labels and boundary tags kept, boundary vertices on the old surface (and
// the surface exactly kept with --keep-surface). Prints the before/after summary; --json
// writes the report (schema incise.improve/1).
#include <cstdio>
#include <iostream>

#include "cli/checks.h"
#include "quality/improve_checks.h"
#include "cli/commands.h"
#include "quality/improve_report.h"
#include "mesh/errors.h"
#include "mesh/io/atomic_file.h"
#include "mesh/io/tet_io.h"
#include "quality/boundary_angle.h"
#include "quality/improve.h"

namespace incise::cli {

void add_improve(CLI::App& app) {
  struct Opts {
    std::string in, out, json;
    ImproveOptions improve;
    bool no_flips = false, no_multi_face = false, no_smoothing = false, fixed_boundary = false, keep_surface = false, insert = false,
         no_surface_flips = false, no_edge_stars = false;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("improve", "Improve element quality by flips, contraction and smoothing (surface and label volumes kept within --volume-tolerance)");
  cmd->add_option("input", o->in, "Tet mesh (.msh .mesh .vtk .vtu .node/.ele)")->required();
  cmd->add_option("-o,--output", o->out, "Improved mesh (format by extension)")->required();
  cmd->add_option("--json", o->json, "Write the before/after report (JSON) to this file");
  cmd->add_option("--time-limit", o->improve.time_limit_s, "Wall-clock limit in seconds")
      ->check(time_limit_range(1e6))
      ->capture_default_str();
  cmd->add_option("--max-work", o->improve.max_work,
                  "Stop after this many operations (tried), whichever of this and --time-limit comes first (0: no "
                  "limit): the same input gives the same mesh on every run and machine")
      ->check(CLI::Range(0, 2000000000))
      ->capture_default_str();
  cmd->add_option("--target-dihedral", o->improve.target_dihedral_deg,
                  "Stop improving a tet once its smallest dihedral angle reaches this (degrees)")
      ->capture_default_str();
  cmd->add_option("--target-max-dihedral", o->improve.target_max_dihedral_deg,
                  "... and its largest is at most this (degrees)")
      ->capture_default_str();
  cmd->add_option("--radius-ratio-floor", o->improve.radius_ratio_floor,
                  "With --insert: an operation may lower its tets' radius ratio down to this, never below (1: never)")
      ->capture_default_str();
  cmd->add_flag("--no-flips", o->no_flips, "Smoothing only (connectivity unchanged)");
  cmd->add_flag("--no-multi-face", o->no_multi_face, "No multi-face removal among the flips (for comparison)");
  cmd->add_flag("--no-smoothing", o->no_smoothing, "Flips only (vertices stay)");
  cmd->add_flag("--insert", o->insert, "Also insert vertices (cavity insertion) where flips, contraction and smoothing are stuck");
  cmd->add_flag("--no-edge-stars", o->no_edge_stars,
                "With --insert: cavities only grown from the bad tet, not also from the tets around its edges (for comparison)");
  cmd->add_option("--max-growth", o->improve.max_growth, "The tet count stays within this factor of the input")
      ->capture_default_str();
  cmd->add_flag("--fixed-boundary", o->fixed_boundary, "Boundary vertices never move");
  cmd->add_flag("--keep-surface", o->keep_surface,
                "Boundary and interface vertices slide only where flat (surface and label volumes kept exactly); "
                "by default they also slide on smooth curved parts, staying on the old surface, while each label's "
                "volume stays within --volume-tolerance");
  cmd->add_option("--volume-tolerance", o->improve.volume_tolerance,
                  "Slides on curved parts may move each label's volume by at most this fraction of it (net; 1: no "
                  "limit in practice)")
      ->check(finite_range(0, 1))
      ->capture_default_str();
  cmd->add_option("--feature-angle", o->improve.feature_angle_deg,
                  "Surface edges bent more than this (degrees) are features: their vertices stay, or slide along "
                  "their line (--feature-line-angle)")
      ->check(finite_range(0, 180))
      ->capture_default_str();
  cmd->add_option("--feature-line-angle", o->improve.feature_line_angle_deg,
                  "A vertex on exactly two feature edges slides along the old line when it bends there by at most "
                  "this (degrees; 0: never), within --volume-tolerance")
      ->check(finite_range(0, 180))
      ->capture_default_str();
  cmd->add_option("--max-slides", o->improve.max_curved_slides,
                  "How often one vertex may slide on a curved part or a feature line in a pass")
      ->check(CLI::Range(0, 1000))
      ->capture_default_str();
  cmd->add_flag("--no-surface-flips", o->no_surface_flips,
                "Boundary flips only between coplanar faces (by default also between faces of one tag that are "
                "not coplanar, within --volume-tolerance)");
  cmd->add_option("--surface-flip-deviation", o->improve.surface_flip_deviation,
                  "A surface flip's old edge stays within this times the shorter of the old and new edge of the new one")
      ->check(finite_range(0, 1))
      ->capture_default_str();
  cmd->callback([o] {
    check_improve_options(o->improve, CliNames{});
    ImproveOptions opt = o->improve;
    opt.flips = !o->no_flips;
    opt.collapse = !o->no_flips;  // contraction changes connectivity too
    opt.multi_face_removal = !o->no_multi_face;
    opt.smoothing = !o->no_smoothing;
    opt.move_surface = !o->fixed_boundary;
    opt.slide_curved = !o->keep_surface;
    opt.insertion = o->insert;
    opt.edge_star_insertion = !o->no_edge_stars;
    opt.reshape_surface = !o->no_surface_flips;
    opt.slide_feature_lines = opt.feature_line_angle_deg > 0;
    OutputTransaction tx;  // the mesh and the report: both written or neither
    reserve_tet_mesh_output(tx, o->out);
    if (!o->json.empty()) tx.reserve(o->json, "--json");
    forbid_tet_mesh_input(tx, o->in);
    ReadReport read;
    TetMesh mesh = read_tet_mesh(o->in, &read);
    const std::optional<BoundaryAngle> bound = smallest_boundary_angle(mesh);
    const ImproveReport r = improve(mesh, opt);
    mesh.discard_change();
    write_tet_mesh(mesh, o->out, {}, tx);
    if (!o->json.empty()) {
      nlohmann::json j = improve_report_json(r);
      j["input"] = o->in;
      j["output"] = o->out;
      j["boundary_angle"] = bound ? nlohmann::json(bound->degrees) : nlohmann::json(nullptr);
      j["max_growth"] = opt.max_growth;
      tx.write_text(o->json, j.dump(2) + "\n");
    }
    tx.commit();
    std::cout << o->in << " (" << read.format << ") -> " << o->out << "\n" << format_improve_report(r);
    // Where the surface itself forbids the target, say so: the tets at its sharpest edge share
    // that edge's angle.
    if (bound && bound->degrees < opt.target_dihedral_deg) {
      char buf[200];
      std::snprintf(buf, sizeof buf,
                    "improve: the boundary allows at most %.2f deg (its sharpest edge, vertices %u-%u), below the "
                    "target %.2f\n",
                    bound->degrees, bound->a.idx(), bound->b.idx(), opt.target_dihedral_deg);
      std::cout << buf;
    }
  });
}

}  // namespace incise::cli
