// incise quality FILE: the mesh quality report (text for people, --json for programs,
// schema in docs/quality-report.md). The report's solver estimate is the formula of
// quality/conditioning.h; unless --solver-estimate formula, this command adds the measured one
// of sim/fem/cg_spectrum.h (a short CG solve; quality/ does not depend on sim/, so it is added here).
#include <cmath>
#include <cstdio>
#include <iostream>

#include "cli/commands.h"
#include "mesh/io/tet_io.h"
#include "quality/report.h"
#include "quality/report_json.h"
#include "sim/fem/cg_spectrum.h"

namespace incise::cli {

namespace {

nlohmann::json measured_json(const MeasuredSolverEstimate& m) {
  auto run = [&](const CgSpectrumRun& r) -> nlohmann::json {
    if (!m.available) return nullptr;
    return {{"iterations_run", r.iterations},
            {"converged", r.converged},
            {"lambda_min", r.ritz.lambda_min},
            {"lambda_max", r.ritz.lambda_max},
            {"kappa", r.kappa},
            {"cg_iterations", std::ceil(r.predicted_iterations)},
            {"ms", r.ms}};
  };
  static const char* axes[] = {"x", "y", "z"};
  return {{"available", m.available},
          {"reason", m.available ? nlohmann::json(nullptr) : nlohmann::json(m.reason)},
          {"source", m.source},
          {"clamp_axis", axes[m.problem.clamp_axis]},
          {"load_axis", axes[m.problem.load_axis]},
          {"fixed_vertices", m.problem.fixed_vertices},
          {"none", run(m.none)},
          {"jacobi", run(m.jacobi)},
          {"ms", m.total_ms}};
}

std::string measured_text(const MeasuredSolverEstimate& m) {
  if (!m.available) return "solver (" + m.source + "): unavailable: " + m.reason;
  char buf[512];
  auto its = [](const CgSpectrumRun& r) {
    return std::to_string(long(std::ceil(r.predicted_iterations))) + (r.converged ? " (converged)" : "");
  };
  std::snprintf(buf, sizeof buf,
                "solver (%s, %zu vertices clamped at min %c, %.0f ms): condition number >= %.4g unpreconditioned, "
                ">= %.4g Jacobi; CG ~%s iterations unpreconditioned, ~%s Jacobi",
                m.source.c_str(), m.problem.fixed_vertices, "xyz"[m.problem.clamp_axis], m.total_ms, m.none.kappa,
                m.jacobi.kappa, its(m.none).c_str(), its(m.jacobi).c_str());
  return buf;
}

}  // namespace

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
    std::string solver_estimate = "measured";
    int lanczos_iterations = MeasuredSolverOptions{}.lanczos_iterations;
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
  cmd->add_option("--solver-estimate", o->solver_estimate,
                  "measured: also run a short CG solve on the mesh's stiffness (Lanczos estimate, costs about 5% "
                  "of a full solve); formula: the formula only (instant)")
      ->check(CLI::IsMember({"measured", "formula"}))
      ->capture_default_str();
  cmd->add_option("--lanczos-iterations", o->lanczos_iterations, "CG iterations of the measured estimate")
      ->check(CLI::Range(1, 1000000))
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
    const bool measure = o->solver_estimate == "measured";
    MeasuredSolverEstimate measured;
    if (measure) {
      MeasuredSolverOptions mo;
      mo.tolerance = o->tolerance;
      mo.poisson_ratio = o->poisson;
      mo.lanczos_iterations = o->lanczos_iterations;
      measured = measure_solver(mesh, mo);
    }
    if (o->json) {
      nlohmann::json j = quality_report_json(r, o->file, read);
      if (measure) j["solver"]["measured"] = measured_json(measured);  // absent: the library's report as is
      std::cout << j.dump(2) << "\n";
      return;
    }
    std::cout << o->file << " (" << read.format << ")";
    if (read.reoriented_tets) std::cout << ": " << read.reoriented_tets << " inverted tets reoriented on read";
    std::cout << "\n" << format_quality_report(r);
    if (measure) std::cout << measured_text(measured) << "\n";
  });
}

}  // namespace incise::cli
