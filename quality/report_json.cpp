#include "quality/report_json.h"

#include <cmath>

namespace incise {

namespace {

using nlohmann::json;

json number(double x) { return std::isfinite(x) ? json(x) : json(nullptr); }

json tet_json(const WorstElement& w) {
  json j = {{"tet", w.tet.idx()}, {"label", w.label}};
  for (const MetricInfo& mi : all_metrics()) j[mi.name] = number(metric_value(w.quality, mi.metric));
  j["min_edge"] = number(w.quality.min_edge);
  j["max_edge"] = number(w.quality.max_edge);
  return j;
}

json stats_json(const MetricStats& s) {
  const MetricInfo& mi = metric_info(s.metric);
  json j = {{"title", mi.title}, {"higher_is_better", mi.higher_is_better}, {"count", s.count}};
  const bool any = s.count > 0;
  j["min"] = any ? number(s.min) : json(nullptr);
  j["mean"] = any ? number(s.mean) : json(nullptr);
  j["max"] = any ? number(s.max) : json(nullptr);
  json p = json::object();
  for (std::size_t k = 0; k < kReportPercentiles.size(); ++k)
    p[std::string("p").append(std::to_string(static_cast<int>(kReportPercentiles[k])))] = any ? number(s.percentiles[k]) : json(nullptr);
  j["percentiles"] = p;
  j["histogram"] = {{"lo", number(s.histogram.lo)},
                    {"hi", number(s.histogram.hi)},
                    {"counts", s.histogram.counts},
                    {"below", s.histogram.below},
                    {"above", s.histogram.above}};
  return j;
}

}  // namespace

json quality_report_json(const QualityReport& r) {
  json j;
  j["schema"] = kQualitySchema;
  const QualityOptions& o = r.options;
  j["options"] = {{"sliver_angle", o.sliver_angle},
                  {"degenerate_volume", o.degenerate_volume},
                  {"worst_metric", metric_info(o.worst_metric).name},
                  {"worst_count", o.worst_count},
                  {"histogram_bins", o.histogram_bins},
                  {"solver_tolerance", o.solver_tolerance},
                  {"poisson_ratio", o.poisson_ratio}};
  j["counts"] = {{"vertices", r.vertices},
                 {"unreferenced_vertices", r.unreferenced_vertices},
                 {"tets", r.tets},
                 {"boundary_faces", r.boundary.faces}};
  j["volume"] = number(r.total_volume);
  j["bounding_box"] = {{"min", {r.bbox_min.x(), r.bbox_min.y(), r.bbox_min.z()}},
                       {"max", {r.bbox_max.x(), r.bbox_max.y(), r.bbox_max.z()}}};
  j["edge_length"] = {{"min", number(r.min_edge)}, {"max", number(r.max_edge)}};
  j["elements"] = {{"inverted", r.inverted},
                   {"degenerate", r.degenerate},
                   {"slivers", r.slivers},
                   {"forced_slivers", r.forced_slivers},
                   {"thin_slivers", r.thin_slivers}};
  json metrics = json::object();
  for (const MetricStats& s : r.metrics) metrics[metric_info(s.metric).name] = stats_json(s);
  j["metrics"] = metrics;
  json worst = json::array();
  for (const WorstElement& w : r.worst) worst.push_back(tet_json(w));
  j["worst"] = {{"metric", metric_info(o.worst_metric).name}, {"elements", worst}};
  const BoundaryTopology& b = r.boundary;
  j["boundary"] = {{"faces", b.faces},
                   {"edges", b.edges},
                   {"open_edges", b.open_edges},
                   {"non_manifold_edges", b.non_manifold_edges},
                   {"misoriented_edges", b.misoriented_edges},
                   {"non_manifold_vertices", b.non_manifold_vertices},
                   {"shells", b.shells},
                   {"closed", b.closed()},
                   {"manifold", b.manifold()},
                   {"oriented", b.oriented()}};
  // The sharpest boundary edge: the bound on the smallest dihedral angle (null without one).
  j["boundary"]["sharpest_edge"] =
      r.boundary_angle ? json{{"degrees", r.boundary_angle->degrees},
                              {"vertices", {r.boundary_angle->a.idx(), r.boundary_angle->b.idx()}}}
                       : json(nullptr);
  j["components"] = r.components;
  json labels = json::array();
  for (const LabelStats& l : r.labels)
    labels.push_back({{"label", l.label},
                      {"tets", l.tets},
                      {"volume", number(l.volume)},
                      {"min_dihedral", number(l.min_dihedral)},
                      {"mean_radius_ratio", number(l.mean_radius_ratio)},
                      {"inverted", l.inverted},
                      {"degenerate", l.degenerate},
                      {"slivers", l.slivers}});
  j["labels"] = labels;
  const SolverEstimate& s = r.solver;
  auto avail = [&](double x) { return s.available ? number(x) : json(nullptr); };
  j["solver"] = {{"available", s.available},
                 {"reason", s.available ? json(nullptr) : json(s.reason)},
                 {"model", "estimate: P1 Laplacian bound x elasticity factor; see docs/quality-report.md"},
                 {"source", "formula"},
                 {"domain_size", avail(s.domain_size)},
                 {"lambda_max_bound", avail(s.lambda_max_bound)},
                 {"lambda_max_vertex", s.available ? json(s.lambda_max_vertex.idx()) : json(nullptr)},
                 {"lambda_min_estimate", avail(s.lambda_min_estimate)},
                 {"kappa_laplace", avail(s.kappa_laplace)},
                 {"elasticity_factor", number(s.elasticity_factor)},
                 {"kappa", avail(s.kappa)},
                 {"cg_iterations", avail(std::ceil(s.cg_iterations))},
                 {"tolerance", number(s.tolerance)},
                 {"poisson_ratio", number(s.poisson_ratio)}};
  return j;
}

json quality_report_json(const QualityReport& report, const std::string& file, const ReadReport& read) {
  json j = quality_report_json(report);
  j["file"] = file;
  j["read"] = {{"format", read.format}, {"reoriented_tets", read.reoriented_tets}, {"skipped_cells", read.skipped_cells}};
  return j;
}

}  // namespace incise
