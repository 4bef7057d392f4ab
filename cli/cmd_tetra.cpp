// incise tetra IN -o OUT: surface or labeled image -> tetrahedral mesh (mesh/tetrahedralize).
// The options are shared with `incise prepare` (cmd_prepare.cpp) through
// add_pipeline_command().
#include <functional>
#include <limits>
#include <iostream>
#include <memory>

#include "cli/checks.h"
#include "cli/commands.h"
#include "mesh/errors.h"
#include "mesh/io/atomic_file.h"
#include "mesh/io/tet_io.h"

#ifdef INCISE_HAVE_TETRA
#include "mesh/tetrahedralize/pipeline.h"
#endif

namespace incise::cli {

#ifdef INCISE_HAVE_TETRA

struct PipelineCli {
  std::string in, out;
  std::string engine = "cgal";
  std::string size = "3%";
  std::string facet_distance;
  double facet_angle = TetraOptions{}.facet_angle;
  double radius_edge = TetraOptions{}.radius_edge;
  double features = TetraOptions{}.features_angle;
  std::string optimize = optimize_str(TetraOptions{}.optimize);
  double optimize_time = TetraOptions{}.optimize_time;
  double sliver_bound = TetraOptions{}.sliver_bound;
  std::string edge_size;
  std::uint32_t seed = 0;
  std::vector<std::string> label_sizes;
  std::size_t max_tets = TetraOptions{}.max_tets;
  bool repair = false;
  bool graded = false;
  std::string voxel = "0.5%";
  double close = -1;
  bool quiet = false;

  PipelineOptions resolve() const {
    PipelineOptions o;
    if (engine == "cgal")
      o.engine = TetraEngine::Cgal;
    else if (engine == "stuffing")
      o.engine = TetraEngine::Stuffing;
    else
      throw InvalidArgument("--engine: expected cgal or stuffing, got '" + engine + "'");
    o.tetra.size = Length::parse(size);
    if (!facet_distance.empty()) o.tetra.facet_distance = Length::parse(facet_distance);
    o.tetra.facet_angle = facet_angle;
    o.tetra.radius_edge = radius_edge;
    o.tetra.features_angle = features;
    o.tetra.optimize = parse_optimize(optimize);
    o.tetra.optimize_time = optimize_time;
    o.tetra.sliver_bound = sliver_bound;
    if (!edge_size.empty()) o.tetra.edge_size = Length::parse(edge_size);
    o.tetra.seed = seed;
    o.tetra.max_tets = max_tets;
    if (graded && o.engine != TetraEngine::Stuffing) throw InvalidArgument("--graded: only with --engine stuffing");
    o.tetra.graded = graded;
    o.tetra.progress = !quiet;
    for (const std::string& ls : label_sizes) {
      const auto eq = ls.find('=');
      if (eq == std::string::npos) throw InvalidArgument("--label-size: expected LABEL=SIZE, got '" + ls + "'");
      try {
        const int label = std::stoi(ls.substr(0, eq));
        const double s = std::stod(ls.substr(eq + 1));
        if (!(s > 0)) throw std::invalid_argument("size");
        o.tetra.label_sizes[label] = s;
      } catch (const std::logic_error&) {
        throw InvalidArgument("--label-size: expected LABEL=SIZE with a positive absolute size, got '" + ls + "'");
      }
    }
    o.repair = repair;
    o.level_set.voxel = Length::parse(voxel);
    o.level_set.closing_radius = close;
    return o;
  }
};

using PipelineRun = std::function<void(const PipelineCli&, const PipelineOptions&)>;

// Adds a subcommand taking IN -o OUT and every pipeline option; `run` gets them resolved.
CLI::App* add_pipeline_command(CLI::App& app, const std::string& name, const std::string& help, PipelineRun run) {
  auto o = std::make_shared<PipelineCli>();
  auto* c = app.add_subcommand(name, help);
  c->add_option("input", o->in, "Closed surface (OBJ, STL, PLY, OFF, ...) or labeled image (.inr, .inr.gz)")
      ->required();
  c->add_option("-o,--output", o->out, "Output tet mesh (.msh .mesh .vtk .vtu .node; by extension)")->required();
  c->add_option("--engine", o->engine, "cgal (Delaunay refinement, accurate) or stuffing (BCC lattice, fast)")
      ->capture_default_str();
  c->add_flag("--graded", o->graded, "Stuffing engine: octree-graded lattice, tets grow away from the surface");
  c->add_option("--size", o->size,
                "Target size: tet circumradius bound; absolute (0.05) or % of the bounding-box diagonal (3%)")
      ->capture_default_str();
  c->add_option("--facet-distance", o->facet_distance, "Surface approximation bound (absolute or %); default size/6");
  c->add_option("--facet-angle", o->facet_angle, "Minimum surface triangle angle, degrees (<= 30)")
      ->check(finite_range(0, 30))
      ->capture_default_str();
  c->add_option("--radius-edge", o->radius_edge, "Tet circumradius / shortest edge bound (>= 2)")
      ->check(finite_range(2, 1e6))
      ->capture_default_str();
  c->add_option("--features", o->features, "Crease angle between face normals for sharp features, degrees (0: off, -1: auto, on for CAD-like creases)")
      ->check(CLI::Validator(
          [](std::string& s) -> std::string {
            double v = 0;
            if (CLI::detail::lexical_cast(s, v) && (v == -1 || (v >= 0 && v <= 180))) return {};
            return "expected -1 (auto), 0 (off) or an angle in [0, 180], got " + s;
          },
          "-1, or in [0, 180]"))
      ->capture_default_str();
  c->add_option("--optimize", o->optimize, "Optimizers: odt,lloyd,perturb,exude in any subset, or none")
      ->capture_default_str();
  c->add_option("--optimize-time", o->optimize_time, "Time limit per optimizer, seconds")
      ->check(time_limit_range(1e6))
      ->capture_default_str();
  c->add_option("--sliver-bound", o->sliver_bound, "perturb/exude target minimum dihedral, degrees (0: best effort)")
      ->check(finite_range(0, 70.5))
      ->capture_default_str();
  c->add_option("--edge-size", o->edge_size, "Sampling along sharp features (absolute or %); default: --size");
  c->add_option("--seed", o->seed, "Random seed (same seed, same mesh)")->capture_default_str();
  c->add_option("--label-size", o->label_sizes, "Images: absolute size for one label, LABEL=SIZE (repeatable)");
  c->add_option("--max-tets", o->max_tets, "Refuse sizes whose estimated tet count is larger")->capture_default_str();
  c->add_flag("--repair", o->repair, "Rebuild a dirty surface (holes, self-intersections, non-manifold) via a level set");
  c->add_option("--voxel", o->voxel, "Level-set voxel size for --repair and the stuffing engine (absolute or %)")
      ->capture_default_str();
  c->add_option("--close", o->close, "Hole-closing radius for --repair (absolute; default: largest hole + 2 voxels)")
      ->check(finite_range(0, std::numeric_limits<double>::max(), "0: no closing"));
  c->add_flag("-q,--quiet", o->quiet, "No progress on stderr (the summary line stays)");
  c->callback([o, run] { run(*o, o->resolve()); });
  return c;
}

const std::string& pipeline_input(const PipelineCli& cli) { return cli.in; }
const std::string& pipeline_output(const PipelineCli& cli) { return cli.out; }
bool pipeline_quiet(const PipelineCli& cli) { return cli.quiet; }

void add_tetra(CLI::App& app) {
  add_pipeline_command(app, "tetra", "Tetrahedralize a closed surface or a labeled 3D image",
                       [](const PipelineCli& cli, const PipelineOptions& opt) {
                         OutputTransaction tx;  // the path is checked before meshing
                         reserve_tet_mesh_output(tx, cli.out);
                         tx.forbid_input(cli.in);
                         PipelineReport rep;
                         auto log = [&](const std::string& m) {
                           if (!cli.quiet) std::cerr << "tetra: " << m << "\n";
                         };
                         TetMesh mesh = mesh_file(cli.in, opt, &rep, log);
                         write_tet_mesh(mesh, cli.out, {}, tx);
                         tx.commit();
                         std::cerr << "tetra: " << rep.stats.summary() << " -> " << cli.out << "\n";
                       });
}

#else  // built without CGAL / OpenVDB

void add_tetra(CLI::App& app) {
  auto* c = app.add_subcommand("tetra", "Tetrahedralize a surface or labeled image (needs INCISE_WITH_CGAL)");
  c->allow_extras();
  c->callback([] { throw Error("tetra: this incise was built without CGAL (configure with -DINCISE_WITH_CGAL=ON)"); });
}

#endif

}  // namespace incise::cli
