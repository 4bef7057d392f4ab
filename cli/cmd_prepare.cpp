// incise prepare IN -o OUT: the whole preparation pipeline in one command:
// check -> repair (when asked) -> tetrahedralize -> improve (flips and smoothing, unless
// --no-improve) -> quality report (text on stdout, JSON
// beside the mesh as <OUT without extension>.quality.json) -> simulation-ready mesh with
// region labels and boundary tags.
#include <cstring>
#include <filesystem>
#include <functional>
#include <iostream>

#include "cli/checks.h"
#include "cli/commands.h"
#include "mesh/errors.h"
#include "mesh/io/atomic_file.h"
#include "mesh/io/tet_io.h"

#ifdef INCISE_HAVE_TETRA
#include "quality/improve_report.h"
#include "mesh/tetrahedralize/pipeline.h"
#include "quality/improve.h"
#include "quality/report.h"
#include "quality/report_json.h"
#endif

namespace incise::cli {

#ifdef INCISE_HAVE_TETRA

// Defined in cmd_tetra.cpp: the subcommand with every pipeline option.
struct PipelineCli;
using PipelineRun = std::function<void(const PipelineCli&, const PipelineOptions&)>;
CLI::App* add_pipeline_command(CLI::App& app, const std::string& name, const std::string& help, PipelineRun run);
const std::string& pipeline_input(const PipelineCli& cli);
const std::string& pipeline_output(const PipelineCli& cli);
bool pipeline_quiet(const PipelineCli& cli);

namespace {

std::string report_path(const std::string& out) {
  std::filesystem::path p(out);
  std::string stem = p.filename().string();
  for (const char* ext : {".node", ".ele", ".msh", ".mesh", ".vtk", ".vtu"})
    if (stem.size() > std::strlen(ext) && stem.compare(stem.size() - std::strlen(ext), std::string::npos, ext) == 0) {
      stem.resize(stem.size() - std::strlen(ext));
      break;
    }
  return (p.parent_path() / (stem + ".quality.json")).string();
}

}  // namespace

void add_prepare(CLI::App& app) {
  auto report_file = std::make_shared<std::string>();
  auto no_improve = std::make_shared<bool>(false);
  auto improve_seconds = std::make_shared<double>(10);
  auto* c = add_pipeline_command(
      app, "prepare", "Surface or labeled image -> checked, simulation-ready tet mesh and quality report",
      [report_file, no_improve, improve_seconds](const PipelineCli& cli, const PipelineOptions& opt) {
        const bool quiet = pipeline_quiet(cli);
        const std::string& out = pipeline_output(cli);
        auto log = [&](const std::string& m) {
          if (!quiet) std::cerr << "prepare: " << m << "\n";
        };
        // The mesh and the report: both paths checked before meshing, both written or neither.
        const std::string json_path = report_file->empty() ? report_path(out) : *report_file;
        OutputTransaction tx;
        reserve_tet_mesh_output(tx, out);
        tx.reserve(json_path, report_file->empty() ? "the quality report" : "--report");
        tx.forbid_input(pipeline_input(cli));
        PipelineReport rep;
        TetMesh mesh = mesh_file(pipeline_input(cli), opt, &rep, log);
        ImproveReport imp;
        if (!*no_improve) {
          ImproveOptions io;
          io.time_limit_s = *improve_seconds;
          // The mesh only approximates the input surface (its report gives the volume against the
          // input's): sliding on it is not limited by volume, the summary line says what it moved.
          io.slide_curved = true;
          io.volume_tolerance = 1;
          // Without a volume limit the surface-moving operations are held to what they were
          // before the allowance existed: one slide a vertex, no feature lines, no surface flips
          // (with them the improvement's tangles can pass the readers' overlap tolerance:
          // docs/improve.md, "Reshaping the surface").
          io.max_curved_slides = 1;
          io.slide_feature_lines = false;
          io.reshape_surface = false;
          imp = improve(mesh, io);
          mesh.discard_change();
          if (!quiet) std::cerr << format_improve_report(imp);
        }
        const QualityReport q = compute_quality_report(mesh);
        write_tet_mesh(mesh, out, {}, tx);
        {
          nlohmann::json j = quality_report_json(q);
          j["file"] = out;  // the mesh it reports on, as `incise quality` names it (incise view REPORT opens it)
          nlohmann::json prep;
          prep["input"] = rep.input;
          prep["image"] = rep.image;
          if (!rep.image) prep["check"] = rep.check.summary();
          prep["repaired"] = rep.repaired;
          if (rep.repaired) {
            prep["repair_voxel"] = rep.repair.voxel;
            prep["repair_closing_radius"] = rep.repair.closing_radius;
            prep["repair_distance_max"] = rep.repair.distance.max;
            prep["repair_distance_mean"] = rep.repair.distance.mean;
          }
          prep["engine"] = rep.stats.engine;
          prep["size"] = rep.stats.size;
          prep["seconds"] = rep.stats.seconds;
          prep["input_volume"] = rep.stats.input_volume;
          prep["messages"] = rep.messages;
          if (!*no_improve) prep["improve"] = improve_report_json(imp);
          j["prepare"] = prep;
          tx.write_text(json_path, j.dump(2) + "\n");
        }
        tx.commit();
        std::cout << format_quality_report(q);
        for (const std::string& m : rep.messages) std::cout << "prepare: " << m << "\n";
        // The meshing figures, then what was written (after the improvement).
        std::cerr << "prepare: " << rep.stats.summary() << "\n";
        std::cerr << "prepare: " << mesh.num_tets() << " tets, " << mesh.num_vertices() << " vertices"
                  << (*no_improve ? "" : " after improvement") << " -> " << out << " (report " << json_path << ")\n";
      });
  c->add_option("--report", *report_file, "Quality report JSON path (default: OUT with .quality.json)");
  c->add_flag("--no-improve", *no_improve, "Skip the quality improvement (flips and smoothing) after meshing");
  c->add_option("--improve-time-limit", *improve_seconds, "Wall-clock limit of the improvement, seconds")
      ->check(time_limit_range(1e6))
      ->capture_default_str();
}

#else  // built without CGAL / OpenVDB

void add_prepare(CLI::App& app) {
  auto* c = app.add_subcommand("prepare", "Surface or image -> simulation-ready mesh (needs INCISE_WITH_CGAL)");
  c->allow_extras();
  c->callback([] { throw Error("prepare: this incise was built without CGAL (configure with -DINCISE_WITH_CGAL=ON)"); });
}

#endif

}  // namespace incise::cli
