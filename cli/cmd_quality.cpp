// incise quality FILE: the mesh quality report (text for people, --json for programs,
// schema in docs/quality-report.md).
#include <iostream>

#include "cli/commands.h"
#include "mesh/io/tet_io.h"
#include "quality/report.h"
#include "quality/report_json.h"

namespace incise::cli {

void add_quality(CLI::App& app) {
  struct Opts {
    std::string file;
    bool json = false;
    int worst = 10;
    std::string metric = "mean_ratio";
    double sliver_angle = 10;
    int bins = 10;
    double degenerate_volume = 1e-12;
    double poisson = 0.45;
    double tolerance = 1e-6;
  };
  auto o = std::make_shared<Opts>();
  std::string names;
  for (const MetricInfo& mi : all_metrics()) names += std::string(names.empty() ? "" : ", ") + mi.name;
  auto* cmd = app.add_subcommand("quality", "Element quality, topology and solver-cost report of a tet mesh");
  cmd->add_option("file", o->file, "Tet mesh (.msh .mesh .vtk .vtu .node/.ele)")->required();
  cmd->add_flag("--json", o->json, "JSON output (schema incise.quality/1)");
  cmd->add_option("--worst", o->worst, "How many worst elements to list")->capture_default_str();
  cmd->add_option("--metric", o->metric, "Metric that ranks the worst elements: " + names)->capture_default_str();
  cmd->add_option("--sliver-angle", o->sliver_angle, "Min dihedral angle (degrees) below which a tet is a sliver")
      ->capture_default_str();
  cmd->add_option("--histogram-bins", o->bins, "Bins per metric histogram")->capture_default_str();
  cmd->add_option("--degenerate-volume", o->degenerate_volume,
                  "A tet with |V| <= this * (longest edge)^3 is degenerate")
      ->capture_default_str();
  cmd->add_option("--poisson-ratio", o->poisson, "Poisson ratio for the condition-number estimate")
      ->capture_default_str();
  cmd->add_option("--tolerance", o->tolerance, "CG relative tolerance for the iteration estimate")
      ->capture_default_str();
  cmd->callback([o] {
    QualityOptions q;
    q.worst_metric = parse_metric(o->metric);
    q.worst_count = o->worst;
    q.sliver_angle = o->sliver_angle;
    q.histogram_bins = o->bins;
    q.degenerate_volume = o->degenerate_volume;
    q.poisson_ratio = o->poisson;
    q.solver_tolerance = o->tolerance;
    ReadReport read;
    TetMesh mesh = read_tet_mesh(o->file, &read);
    QualityReport r = compute_quality_report(mesh, q);
    if (o->json) {
      std::cout << quality_report_json(r, o->file, read).dump(2) << "\n";
      return;
    }
    std::cout << o->file << " (" << read.format << ")";
    if (read.reoriented_tets) std::cout << ": " << read.reoriented_tets << " inverted tets reoriented on read";
    std::cout << "\n" << format_quality_report(r);
  });
}

}  // namespace incise::cli
