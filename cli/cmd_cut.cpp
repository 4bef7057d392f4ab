// incise cut IN -o OUT: progressive blade cuts (a segment swept in N steps), a plane cut, or a
// cut by a triangulated surface; subdivision (remesh along the blade, separate) or removal.
// Cut faces carry boundary tag 2 where the format keeps tags (.msh, .mesh). The JSON report's
// times cover the cut steps only, not reading or writing.
#include <algorithm>
#include <cmath>
#include <iostream>

#include <nlohmann/json.hpp>

#include "cli/checks.h"
#include "cli/commands.h"
#include "cut/blade_path.h"
#include "cut/cutter.h"
#include "mesh/errors.h"
#include "mesh/io/atomic_file.h"
#include "mesh/io/input_checks.h"
#include "mesh/io/surface.h"
#include "mesh/io/tet_io.h"
#include "quality/metrics.h"

namespace incise::cli {

void add_cut(CLI::App& app) {
  struct Opts {
    std::string in, out, json, mode = "subdivide", surface, path;
    std::vector<double> blade, sweep, plane;
    int steps = 1;
    double snap = 0.05, budget_ms = 0, finish_insert = CutOptions{}.finish_insertion_below_deg;
    int work = CutOptions::kDefaultImproveWork, finish_work = CutOptions{}.finish_improve_work;
    bool no_improve = false, quiet = false, exact_volumes = CutOptions{}.exact_volumes;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("cut", "Cut a tet mesh with a swept blade, a plane or a surface");
  cmd->add_option("input", o->in, "Tet mesh (.msh .mesh .vtk .vtu .node)")->required();
  cmd->add_option("-o,--output", o->out, "Cut mesh (by extension; cut faces tagged 2 in .msh/.mesh)")->required();
  cmd->add_option("--blade", o->blade, "Blade segment A-B: AX AY AZ BX BY BZ")->expected(6);
  cmd->add_option("--sweep", o->sweep, "Blade motion D over the whole cut: DX DY DZ")->expected(3);
  auto* steps_opt = cmd->add_option("--steps", o->steps, "Progressive steps: the blade moves D/N per step (N cuts)")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  cmd->add_option("--path", o->path,
                  "Instead of --blade/--sweep: a blade path file, one position 'AX AY AZ BX BY BZ' per line (the "
                  "first places the blade, each later one is a step; '#' comments)");
  cmd->add_option("--plane", o->plane, "Instead of a blade: plane through P with normal N: PX PY PZ NX NY NZ")
      ->expected(6);
  cmd->add_option("--surface", o->surface, "Instead of a blade: cut along a triangulated surface (OFF, OBJ, STL, ...)");
  cmd->add_option("--mode", o->mode, "subdivide (remesh along the blade, separate) or remove (carve touched tets)")
      ->check(CLI::IsMember({"subdivide", "remove"}))
      ->capture_default_str();
  cmd->add_option("--snap", o->snap,
                  "Snap threshold relative to the local edge length: vertices this close to the blade are "
                  "treated as on it (fewer slivers, cut surface up to this far from the blade)")
      ->check(CLI::Validator(
          [](std::string& s) -> std::string {
            double v = 0;
            if (!CLI::detail::lexical_cast(s, v)) return "'" + s + "' is not a number";
            return snap_error(v);
          },
          "in [0, 0.5)"))
      ->capture_default_str();
  cmd->add_flag("--no-improve", o->no_improve, "No local flips and smoothing after each step");
  cmd->add_flag("--exact-volumes,!--no-exact-volumes", o->exact_volumes,
                "Keep every label's volume (and the body's) to rounding (the default): a contraction that moves "
                "the surface moves its kept vertex by what gives the volume back. --no-exact-volumes takes "
                "those contractions as they are, moving each label by a hair (docs/cut.md#label-volumes)");
  cmd->add_option("--improve-work", o->work,
                  "Operations the local improvement may attempt per step (0: no cap). The default result is "
                  "reproducible: the same command gives the same mesh on every run")
      ->check(CLI::Range(0, 100000000))
      ->capture_default_str();
  cmd->add_option("--improve-budget-ms", o->budget_ms,
                  "Wall-clock cap of the local improvement per step, on top of --improve-work (0: none, the "
                  "default; a time cap makes the output depend on the machine's speed and load)")
      ->check(time_limit_range(1e6))
      ->capture_default_str();
  auto* finish_opt = cmd->add_option("--finish-insert", o->finish_insert,
                  "After the blade: insert vertices into tets whose smallest dihedral angle stays below this many "
                  "degrees (where cuts cross or meet the surface at a small angle; 0: no insertion)")
      ->check(finite_range(0.0, 90.0))
      ->capture_default_str();
  auto* finish_work_opt = cmd->add_option("--finish-work", o->finish_work,
                  "Operations of the improvement once the blade is withdrawn (an insertion attempt counts 10; "
                  "0: none). Like --improve-work, a count: the result does not depend on the machine")
      ->check(CLI::Range(0, 100000000))
      ->capture_default_str();
  cmd->add_option("--json", o->json, "Write the cut report (JSON) here");
  cmd->add_flag("-q,--quiet", o->quiet, "No per-step progress on stderr");
  cmd->callback([o, steps_opt, finish_opt, finish_work_opt] {
    const int kinds =
        int(!o->blade.empty()) + int(!o->plane.empty()) + int(!o->surface.empty()) + int(!o->path.empty());
    if (kinds != 1) throw InvalidArgument("cut: give exactly one of --blade (with --sweep), --path, --plane, --surface");
    const bool blade = !o->blade.empty() || !o->path.empty();
    if (!o->blade.empty() && o->sweep.empty()) throw InvalidArgument("cut: --blade needs --sweep DX DY DZ");
    // A plane or a surface cut is one step with nothing swept: the options would be ignored.
    if (o->blade.empty() && (!o->sweep.empty() || steps_opt->count() > 0))
      throw InvalidArgument(o->path.empty() ? "cut: --sweep and --steps go with --blade only"
                                            : "cut: --sweep and --steps go with --blade, not --path (a path gives every step)");
    if (!blade && finish_opt->count() > 0)
      throw InvalidArgument("cut: --finish-insert goes with --blade or --path only (a plane or surface cut has no withdrawn blade)");
    if (!blade && finish_work_opt->count() > 0)
      throw InvalidArgument("cut: --finish-work goes with --blade or --path only (a plane or surface cut has no withdrawn blade)");
    for (const auto* v : {&o->blade, &o->sweep, &o->plane})
      for (double x : *v)
        if (!std::isfinite(x) || std::abs(x) > 1e15)
          throw InvalidArgument("cut: coordinates must be finite numbers of magnitude at most 1e15, got " +
                                number_text(x));
    if (!o->blade.empty()) {
      const std::string why = degenerate_sweep(Vec3(o->blade[0], o->blade[1], o->blade[2]),
                                               Vec3(o->blade[3], o->blade[4], o->blade[5]),
                                               Vec3(o->sweep[0], o->sweep[1], o->sweep[2]));
      if (!why.empty()) throw InvalidArgument("cut: --blade/--sweep: " + why);
    }
    OutputTransaction tx;  // the mesh and the report: both written or neither
    reserve_tet_mesh_output(tx, o->out);
    if (!o->json.empty()) tx.reserve(o->json, "--json");
    forbid_tet_mesh_input(tx, o->in);
    for (const std::string* f : {&o->surface, &o->path})
      if (!f->empty()) tx.forbid_input(*f);
    TetMesh mesh = read_tet_mesh(o->in);
    mesh.discard_change();
    SurfaceMesh surface;
    if (!o->surface.empty()) surface = read_surface(o->surface);
    std::vector<BladeSegment> path;
    if (!o->path.empty()) path = read_blade_path(o->path);

    CutOptions opt;
    opt.mode = o->mode == "remove" ? CutMode::Remove : CutMode::Subdivide;
    opt.snap = o->snap;
    opt.improve = !o->no_improve;
    opt.improve_budget_ms = o->budget_ms;
    opt.improve_options.max_work = o->work;
    opt.finish_insertion_below_deg = o->finish_insert;
    opt.finish_improve_work = o->finish_work;
    opt.exact_volumes = o->exact_volumes;
    const QualityRange before = quality_range(mesh);
    const std::size_t tets_before = mesh.num_tets(), verts_before = mesh.num_vertices();

    Cutter cutter(mesh, opt);
    nlohmann::json steps = nlohmann::json::array();
    std::size_t tets_cut = 0, tets_added = 0, vertices_added = 0, duplicated = 0, faces = 0, fragments = 0;
    double ms_total = 0, ms_max = 0, area = 0, exposed = 0;
    // k: the step's number; the blade's withdrawal (finish()) is recorded as "finish".
    auto record = [&](const CutStepReport& r, int k, bool finish = false) {
      tets_cut += r.tets_cut;
      tets_added += r.tets_added;
      vertices_added += r.vertices_added;
      duplicated += r.vertices_duplicated;
      faces += r.cut_faces;
      area += r.cut_area;
      exposed += r.exposed_area;
      fragments += r.fragments.size();
      ms_total += r.ms;
      ms_max = std::max(ms_max, r.ms);
      steps.push_back({{"step", k},
                       {"finish", finish},
                       {"tets_cut", r.tets_cut},
                       {"tets_added", r.tets_added},
                       {"vertices_added", r.vertices_added},
                       {"vertices_duplicated", r.vertices_duplicated},
                       {"cut_faces", r.cut_faces},
                       {"fragments", r.fragments.size()},
                       {"ms", r.ms},
                       {"ms_improve", r.ms_improve}});
      if (!o->quiet)
        std::cerr << "cut: " << (finish ? std::string("finish (blade withdrawn)") : "step " + std::to_string(k)) << ": "
                  << r.tets_cut << " tets cut, +" << r.tets_added << " tets, " << r.vertices_duplicated
                  << " vertices duplicated, " << r.ms << " ms" << (finish ? " (the last front's improvement)" : "") << "\n";
    };
    if (!o->blade.empty()) {
      const Vec3 a(o->blade[0], o->blade[1], o->blade[2]), b(o->blade[3], o->blade[4], o->blade[5]);
      const Vec3 d(o->sweep[0], o->sweep[1], o->sweep[2]);
      cutter.start({a, b});
      for (int k = 1; k <= o->steps; ++k) {
        const Vec3 off = d * (double(k) / o->steps);
        record(cutter.advance({a + off, b + off}), k);
      }
      // The blade is withdrawn: the last front's tets get the improvement with it free.
      CutStepReport fin = cutter.finish();
      if (!fin.change.empty()) record(std::move(fin), o->steps + 1, true);
    } else if (!path.empty()) {
      cutter.start(path[0]);
      for (std::size_t k = 1; k < path.size(); ++k) record(cutter.advance(path[k]), int(k));
      CutStepReport fin = cutter.finish();
      if (!fin.change.empty()) record(std::move(fin), int(path.size()), true);
    } else if (!o->plane.empty()) {
      record(cutter.cut_plane(Vec3(o->plane[0], o->plane[1], o->plane[2]), Vec3(o->plane[3], o->plane[4], o->plane[5])),
             1);
    } else {
      std::vector<CutTriangle> tris;
      for (const auto& t : surface.triangles)
        tris.push_back({{surface.vertices[t[0]], surface.vertices[t[1]], surface.vertices[t[2]]}});
      record(cutter.cut_surface(tris), 1);
    }
    // Remove mode can carve the whole body: a mesh without tets is no mesh (readers refuse it).
    if (mesh.num_tets() == 0) throw InvalidArgument("cut: the cut removes every tet of " + o->in + "; nothing written");
    // Nothing changed at all: a cut along a plane of mesh faces splits no tet but opens faces.
    if (tets_cut == 0 && tets_added == 0 && vertices_added == 0 && faces == 0)
      std::cerr << "cut: warning: the " << (!blade ? (o->plane.empty() ? "surface" : "plane") : "blade")
                << " does not reach the mesh; " << o->out << " is the input unchanged\n";
    const QualityRange after = quality_range(mesh);
    write_tet_mesh(mesh, o->out, {}, tx);
    std::cerr << "cut: " << o->in << " -> " << o->out << ": " << tets_before << " -> " << mesh.num_tets() << " tets, "
              << verts_before << " -> " << mesh.num_vertices() << " vertices; " << tets_cut << " tets cut, "
              << duplicated << " vertices duplicated, " << fragments << " fragment(s); min dihedral " << before.min_dihedral
              << " -> " << after.min_dihedral << " deg; " << ms_total << " ms (max step " << ms_max << " ms)\n";
    if (!o->json.empty()) {
      nlohmann::json j = {{"schema", "incise.cut/1"},
                          {"input", o->in},
                          {"output", o->out},
                          {"mode", o->mode},
                          {"snap", o->snap},
                          {"improve", !o->no_improve},
                          {"tets_before", tets_before},
                          {"tets_after", mesh.num_tets()},
                          {"tets_cut", tets_cut},
                          {"tets_added", tets_added},
                          {"vertices_added", vertices_added},
                          {"vertices_duplicated", duplicated},
                          {"cut_faces", faces},
                          {"cut_area", area},
                          {"exposed_area", exposed},
                          {"fragments", fragments},
                          {"min_dihedral_before", before.min_dihedral},
                          {"max_dihedral_before", before.max_dihedral},
                          {"min_dihedral_after", after.min_dihedral},
                          {"max_dihedral_after", after.max_dihedral},
                          {"ms_total", ms_total},
                          {"ms_max_step", ms_max},
                          {"steps", steps}};
      tx.write_text(o->json, j.dump(2) + "\n");
    }
    tx.commit();
  });
}

}  // namespace incise::cli
