// incise.quality: the report of `incise quality --json` as a dict (same writer,
// quality/report_json.h), and its text form.
#include "python/bindings.h"

#include "mesh/errors.h"
#include "mesh/io/tet_io.h"
#include "quality/report.h"
#include "quality/report_json.h"

namespace incise::python {

py::object json_to_python(const std::string& text) { return py::module_::import("json").attr("loads")(text); }

namespace {

QualityOptions quality_options(int worst, const std::string& metric, double sliver_angle, int bins,
                               double degenerate_volume, double poisson, double tolerance) {
  QualityOptions q;
  q.worst_count = worst;
  q.worst_metric = parse_metric(metric);
  q.sliver_angle = sliver_angle;
  q.histogram_bins = bins;
  q.degenerate_volume = degenerate_volume;
  q.poisson_ratio = poisson;
  q.solver_tolerance = tolerance;
  return q;
}

// Empty (rest positions) when not given.
std::vector<Vec3> positions_or_rest(const TetMesh& mesh, const py::object& positions) {
  if (positions.is_none()) return {};
  return to_points(positions, mesh.vertex_capacity(), "positions");
}

}  // namespace

void bind_quality(py::module_& m) {
  // The mesh, or a path: then the mesh is read and "file" / "read" are added exactly as the
  // CLI does, so the dict equals `incise quality FILE --json`.
  m.def(
      "quality",
      [](const py::object& mesh_or_path, int worst, const std::string& metric, double sliver_angle, int bins,
         double degenerate_volume, double poisson, double tolerance, const py::object& positions) {
        const QualityOptions q = quality_options(worst, metric, sliver_angle, bins, degenerate_volume, poisson, tolerance);
        if (py::isinstance<py::str>(mesh_or_path)) {
          const std::string file = mesh_or_path.cast<std::string>();
          ReadReport read;
          const TetMesh mesh = read_tet_mesh(file, &read);
          const std::vector<Vec3> p = positions_or_rest(mesh, positions);
          return json_to_python(quality_report_json(compute_quality_report(mesh, q, p), file, read).dump());
        }
        const TetMesh& mesh = mesh_or_path.cast<const TetMesh&>();
        const std::vector<Vec3> p = positions_or_rest(mesh, positions);
        return json_to_python(quality_report_json(compute_quality_report(mesh, q, p)).dump());
      },
      py::arg("mesh"), py::kw_only(), py::arg("worst") = 10, py::arg("metric") = "mean_ratio",
      py::arg("sliver_angle") = 10.0, py::arg("histogram_bins") = 10, py::arg("degenerate_volume") = 1e-12,
      py::arg("poisson_ratio") = 0.45, py::arg("tolerance") = 1e-6, py::arg("positions") = py::none(),
      "Quality report (schema incise.quality/1, docs/quality-report.md) of a TetMesh or a mesh file; "
      "positions (vertex_capacity by 3) rates a deformed configuration.");
  m.def(
      "quality_text",
      [](const TetMesh& mesh) { return format_quality_report(compute_quality_report(mesh)); }, py::arg("mesh"),
      "The report as `incise quality` prints it");
  m.def(
      "tet_quality",
      [](const TetMesh& mesh, const std::string& metric) {
        const Metric mt = parse_metric(metric);
        const std::vector<TetId> ids = mesh.tets();
        py::array_t<double> a(static_cast<py::ssize_t>(ids.size()));
        for (std::size_t i = 0; i < ids.size(); ++i) a.mutable_data()[i] = metric_value(tet_quality(mesh, ids[i]), mt);
        return a;
      },
      py::arg("mesh"), py::arg("metric") = "mean_ratio", "One metric per live tet (order of TetMesh.tets)");
  py::list names;
  for (const MetricInfo& mi : all_metrics()) names.append(mi.name);
  m.attr("metrics") = names;
}

}  // namespace incise::python
