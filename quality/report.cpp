#include "quality/report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numeric>

#include "mesh/errors.h"
#include "quality/thin_parts.h"

namespace incise {

namespace {

void check_options(const QualityOptions& o) {
  if (!(o.sliver_angle >= 0 && o.sliver_angle <= 180)) throw InvalidArgument("quality: sliver angle must be in [0, 180] degrees");
  if (!(o.degenerate_volume >= 0 && o.degenerate_volume < 1))
    throw InvalidArgument("quality: degenerate volume threshold must be in [0, 1)");
  if (o.worst_count < 0) throw InvalidArgument("quality: worst count must be >= 0");
  if (o.histogram_bins < 1 || o.histogram_bins > 10000) throw InvalidArgument("quality: histogram bins must be in [1, 10000]");
}

Histogram make_histogram(std::span<const double> x, double lo, double hi, int bins) {
  Histogram h;
  h.lo = lo;
  h.hi = hi;
  h.counts.assign(bins, 0);
  const double scale = hi > lo ? bins / (hi - lo) : 0.0;
  for (double v : x) {
    if (v < lo) {
      ++h.below;
    } else if (v > hi) {
      ++h.above;
    } else {
      auto b = static_cast<std::size_t>((v - lo) * scale);
      ++h.counts[std::min<std::size_t>(b, bins - 1)];
    }
  }
  return h;
}

// Summarizes x (reordered in place).
MetricStats summarize(Metric m, std::vector<double>& x, int bins) {
  MetricStats s;
  s.metric = m;
  s.count = x.size();
  const MetricInfo& info = metric_info(m);
  if (x.empty()) {
    s.histogram = make_histogram(x, info.hist_lo, info.hist_hi, bins);
    return s;
  }
  auto [mn, mx] = std::minmax_element(x.begin(), x.end());
  s.min = *mn;
  s.max = *mx;
  // Pairwise-free but compensated: the mean of 1e6 volumes keeps its digits.
  double sum = 0, c = 0;
  for (double v : x) {
    double y = v - c, t = sum + y;
    c = (t - sum) - y;
    sum = t;
  }
  s.mean = sum / static_cast<double>(x.size());
  double lo = info.hist_lo, hi = info.hist_hi;
  if (m == Metric::Volume) {
    lo = 0;
    hi = std::max(0.0, s.max);
  }
  s.histogram = make_histogram(x, lo, hi, bins);

  const std::size_t n = x.size();
  auto begin = x.begin();
  for (std::size_t k = 0; k < kReportPercentiles.size(); ++k) {
    double pos = kReportPercentiles[k] / 100.0 * static_cast<double>(n - 1);
    auto i = static_cast<std::size_t>(std::floor(pos));
    double frac = pos - static_cast<double>(i);
    std::nth_element(begin, x.begin() + i, x.end());
    double a = x[i], b = a;
    if (frac > 0 && i + 1 < n) b = *std::min_element(x.begin() + i + 1, x.end());
    s.percentiles[k] = a + frac * (b - a);
    begin = x.begin() + i;  // percentiles ascend: earlier elements are already below
  }
  return s;
}

}  // namespace

QualityReport compute_quality_report(const TetMesh& mesh, const QualityOptions& options, std::span<const Vec3> positions) {
  check_options(options);
  if (!positions.empty() && positions.size() < mesh.vertex_capacity())
    throw InvalidArgument("quality: positions must have one entry per vertex id");
  QualityReport r;
  r.options = options;
  r.vertices = mesh.num_vertices();
  r.tets = mesh.num_tets();
  auto pos = [&](VertexId v) -> const Vec3& { return positions.empty() ? mesh.rest(v) : positions[v.idx()]; };

  bool first = true;
  for (std::uint32_t i = 0; i < mesh.vertex_capacity(); ++i) {
    VertexId v(i);
    if (!mesh.is_alive(v)) continue;
    if (mesh.incident_tets(v).empty()) ++r.unreferenced_vertices;
    if (first) r.bbox_min = r.bbox_max = pos(v);
    r.bbox_min = r.bbox_min.cwiseMin(pos(v));
    r.bbox_max = r.bbox_max.cwiseMax(pos(v));
    first = false;
  }

  const std::vector<TetId> ids = mesh.tets();
  const std::size_t n = ids.size();
  std::vector<std::vector<double>> values(kNumMetrics, std::vector<double>(n));
  std::map<int, LabelStats> labels;
  std::vector<TetId> sliver_ids;  // for the forced and thin counts
  double min_edge = std::numeric_limits<double>::infinity(), max_edge = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const TetQuality q = tet_quality(mesh, ids[i], positions);
    for (int m = 0; m < kNumMetrics; ++m) values[m][i] = metric_value(q, static_cast<Metric>(m));
    min_edge = std::min(min_edge, q.min_edge);
    max_edge = std::max(max_edge, q.max_edge);
    r.total_volume += q.volume;

    const int label = mesh.label(ids[i]);
    LabelStats& ls = labels[label];
    if (ls.tets == 0) {
      ls.label = label;
      ls.min_dihedral = q.min_dihedral;
    }
    ++ls.tets;
    ls.volume += q.volume;
    ls.min_dihedral = std::min(ls.min_dihedral, q.min_dihedral);
    ls.mean_radius_ratio += q.radius_ratio;  // divided below

    const double lmax = q.max_edge;
    if (std::abs(q.volume) <= options.degenerate_volume * lmax * lmax * lmax) {
      ++r.degenerate;
      ++ls.degenerate;
    } else if (q.volume < 0) {
      ++r.inverted;
      ++ls.inverted;
    } else if (q.min_dihedral < options.sliver_angle) {
      ++r.slivers;
      ++ls.slivers;
      sliver_ids.push_back(ids[i]);
    }
  }
  if (n > 0) {
    r.min_edge = min_edge;
    r.max_edge = max_edge;
  }
  for (auto& [label, ls] : labels) {
    ls.mean_radius_ratio /= static_cast<double>(ls.tets);
    r.labels.push_back(ls);
  }

  // Worst elements before the summaries reorder the values.
  {
    const int wm = static_cast<int>(options.worst_metric);
    const bool higher_better = metric_info(options.worst_metric).higher_is_better;
    const std::vector<double>& key = values[wm];
    std::vector<std::uint32_t> order(n);
    std::iota(order.begin(), order.end(), 0u);
    const std::size_t k = std::min<std::size_t>(n, static_cast<std::size_t>(options.worst_count));
    std::partial_sort(order.begin(), order.begin() + k, order.end(), [&](std::uint32_t a, std::uint32_t b) {
      if (key[a] != key[b]) return higher_better ? key[a] < key[b] : key[a] > key[b];
      return a < b;  // ties: lowest id first, so the list is deterministic
    });
    for (std::size_t j = 0; j < k; ++j) {
      TetId t = ids[order[j]];
      r.worst.push_back({t, mesh.label(t), tet_quality(mesh, t, positions)});
    }
  }

  r.metrics.reserve(kNumMetrics);
  for (int m = 0; m < kNumMetrics; ++m) {
    r.metrics.push_back(summarize(static_cast<Metric>(m), values[m], options.histogram_bins));
    std::vector<double>().swap(values[m]);  // release as we go: peak memory stays one copy
  }

  r.boundary = boundary_topology(mesh);
  r.boundary_angle = smallest_boundary_angle(mesh);
  if (r.slivers > 0) {
    std::vector<TetId> forced;
    if (r.boundary_angle && r.boundary_angle->degrees < options.sliver_angle)
      forced = sharp_boundary(mesh, options.sliver_angle).tets;
    r.forced_slivers = forced.size();
    std::erase_if(sliver_ids, [&](TetId t) { return std::binary_search(forced.begin(), forced.end(), t); });
    r.thin_slivers = across_thin_parts(mesh, sliver_ids).size();
  }
  r.components = tet_components(mesh).count;
  SolverEstimateOptions so;
  so.tolerance = options.solver_tolerance;
  so.poisson_ratio = options.poisson_ratio;
  so.degenerate_volume = options.degenerate_volume;
  r.solver = estimate_solver(mesh, so, positions);
  return r;
}

namespace {

std::string fmt(const char* f, double x) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, x);
  return buf;
}
std::string num(double x) {
  if (x == 0) return "0";
  double ax = std::abs(x);
  if (ax >= 1e5 || ax < 1e-3) return fmt("%.3e", x);
  return fmt("%.4g", x);
}
std::string pad(std::string s, std::size_t w) {
  if (s.size() < w) s.insert(0, w - s.size(), ' ');
  return s;
}
std::string padr(std::string s, std::size_t w) {
  if (s.size() < w) s.append(w - s.size(), ' ');
  return s;
}
std::string plural(std::size_t n, const char* one, const char* many) {
  return std::to_string(n) + " " + (n == 1 ? one : many);
}

}  // namespace

std::string format_quality_report(const QualityReport& r) {
  std::string o;
  auto line = [&](const std::string& s) { o += s + "\n"; };
  line("vertices " + std::to_string(r.vertices) + " (" + std::to_string(r.unreferenced_vertices) +
       " unreferenced), tets " + std::to_string(r.tets) + ", boundary faces " + std::to_string(r.boundary.faces));
  line("volume " + num(r.total_volume) + ", bbox [" + num(r.bbox_min.x()) + ", " + num(r.bbox_max.x()) + "] x [" +
       num(r.bbox_min.y()) + ", " + num(r.bbox_max.y()) + "] x [" + num(r.bbox_min.z()) + ", " +
       num(r.bbox_max.z()) + "], edges " + num(r.min_edge) + " .. " + num(r.max_edge));
  const BoundaryTopology& b = r.boundary;
  line("topology: " + plural(r.components, "component", "components") + ", " +
       plural(b.shells, "boundary shell", "boundary shells") + ", " + (b.closed() ? "closed" : "OPEN") + ", " +
       (b.manifold() ? "manifold" : "NON-MANIFOLD") +
       (b.oriented() ? "" : ", MIS-ORIENTED") + " (" + std::to_string(b.open_edges) + " open, " +
       std::to_string(b.non_manifold_edges) + " non-manifold, " + std::to_string(b.misoriented_edges) +
       " mis-oriented edges; " + std::to_string(b.non_manifold_vertices) + " non-manifold vertices)");
  if (r.boundary_angle)
    line("boundary: sharpest edge " + fmt("%.2f", r.boundary_angle->degrees) + " deg (vertices " +
         std::to_string(r.boundary_angle->a.idx()) + "-" + std::to_string(r.boundary_angle->b.idx()) +
         "): no mesh of this surface has a larger smallest dihedral angle");
  line("elements: " + std::to_string(r.inverted) + " inverted, " + std::to_string(r.degenerate) + " degenerate, " +
       std::to_string(r.slivers) + " slivers (min dihedral < " + num(r.options.sliver_angle) + " deg" +
       (r.forced_slivers ? "; " + std::to_string(r.forced_slivers) + " of them forced by boundary edges sharper than that"
                         : std::string()) +
       (r.thin_slivers ? "; " + std::to_string(r.thin_slivers) +
                             (r.forced_slivers ? " more" : " of them") + " across parts thinner than a quarter of their longest edge"
                       : std::string()) +
       ")");
  line("");

  std::string head = padr("metric", 20);
  for (const char* c : {"min", "p1", "p5", "p50", "p95", "p99", "max", "mean"}) head += pad(c, 11);
  line(head);
  for (const MetricStats& s : r.metrics) {
    const MetricInfo& mi = metric_info(s.metric);
    std::string row = padr(mi.title, 20);
    if (s.count == 0) {
      line(row + "   (no tets)");
      continue;
    }
    row += pad(num(s.min), 11);
    for (double p : s.percentiles) row += pad(num(p), 11);
    row += pad(num(s.max), 11) + pad(num(s.mean), 11);
    line(row);
  }

  const MetricInfo& wi = metric_info(r.options.worst_metric);
  const MetricStats& hs = r.stats(r.options.worst_metric);
  if (hs.count > 0) {
    line("");
    line(std::string("histogram of ") + wi.name + ":");
    std::size_t peak = std::max<std::size_t>(1, *std::max_element(hs.histogram.counts.begin(), hs.histogram.counts.end()));
    const int k = static_cast<int>(hs.histogram.counts.size());
    const double w = (hs.histogram.hi - hs.histogram.lo) / k;
    if (hs.histogram.below) line(pad("< " + num(hs.histogram.lo), 22) + pad(std::to_string(hs.histogram.below), 10));
    for (int i = 0; i < k; ++i) {
      std::size_t c = hs.histogram.counts[i];
      std::string bar(c ? std::max<std::size_t>(1, 40 * c / peak) : 0, '#');
      std::string range = "[";
      range += num(hs.histogram.lo + i * w) + ", " + num(hs.histogram.lo + (i + 1) * w) + (i + 1 == k ? "]" : ")");
      line(pad(range, 22) +
           pad(std::to_string(c), 10) + (bar.empty() ? "" : " " + bar));
    }
    if (hs.histogram.above) line(pad("> " + num(hs.histogram.hi), 22) + pad(std::to_string(hs.histogram.above), 10));
  }

  if (!r.worst.empty()) {
    line("");
    line("worst " + std::to_string(r.worst.size()) + " by " + wi.name + ":");
    // The ranking metric first, then the usual suspects (without repeating it).
    std::vector<Metric> cols = {r.options.worst_metric};
    for (Metric m : {Metric::Volume, Metric::MinDihedral, Metric::MaxDihedral, Metric::MeanRatio, Metric::RadiusRatio})
      if (m != r.options.worst_metric && cols.size() < 5) cols.push_back(m);
    std::string head = pad("tet", 10) + pad("label", 7);
    for (Metric m : cols) head += pad(metric_info(m).name, 16);
    line(head);
    for (const WorstElement& we : r.worst) {
      std::string row = pad(std::to_string(we.tet.idx()), 10) + pad(std::to_string(we.label), 7);
      for (Metric m : cols) {
        const double x = metric_value(we.quality, m);
        row += pad(m == Metric::MinDihedral || m == Metric::MaxDihedral ? fmt("%.2f", x) : num(x), 16);
      }
      line(row);
    }
  }

  if (!r.labels.empty()) {
    line("");
    line(pad("label", 8) + pad("tets", 10) + pad("volume", 12) + pad("min dih", 10) + pad("mean rr", 10) +
         pad("inverted", 10) + pad("degen", 8) + pad("slivers", 9));
    for (const LabelStats& ls : r.labels)
      line(pad(std::to_string(ls.label), 8) + pad(std::to_string(ls.tets), 10) + pad(num(ls.volume), 12) +
           pad(fmt("%.2f", ls.min_dihedral), 10) + pad(fmt("%.4f", ls.mean_radius_ratio), 10) +
           pad(std::to_string(ls.inverted), 10) + pad(std::to_string(ls.degenerate), 8) +
           pad(std::to_string(ls.slivers), 9));
  }

  line("");
  const SolverEstimate& s = r.solver;
  if (s.available) {
    line("solver (formula): condition number ~" + num(s.kappa) + " (Laplacian " + num(s.kappa_laplace) + " x " +
         num(s.elasticity_factor) + " for nu = " + num(s.poisson_ratio) + "), CG ~" +
         fmt("%.0f", std::ceil(s.cg_iterations)) + " iterations to " + fmt("%g", s.tolerance) +
         " unpreconditioned; stiffest at vertex " + std::to_string(s.lambda_max_vertex.idx()));
  } else {
    line("solver (formula): unavailable: " + s.reason);
  }
  return o;
}

}  // namespace incise
