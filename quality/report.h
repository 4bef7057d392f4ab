#pragma once
// The mesh quality report: counts, every metric of quality/metrics.h summarized (min, mean,
// max, percentiles, histogram), inverted / degenerate / sliver counts, the worst elements,
// boundary topology, connected components, a per-label breakdown and the solver estimate
// of quality/conditioning.h. O(mesh) time and memory (about 80 bytes per tet).
//
// Element classes are disjoint: degenerate when |V| <= degenerate_volume * l_max^3,
// else inverted when V < 0, else a sliver when min dihedral < sliver_angle.
// The JSON form (schema "incise.quality/1") is written by the CLI; see
// docs/quality-report.md.
#include <array>
#include <span>
#include <string>
#include <optional>
#include <vector>

#include "mesh/tet_mesh.h"
#include "quality/boundary_angle.h"
#include "quality/components.h"
#include "quality/conditioning.h"
#include "quality/metrics.h"

namespace incise {

struct QualityOptions {
  double sliver_angle = 10.0;         // degrees: min dihedral below this makes a sliver
  double degenerate_volume = 1e-12;   // relative: |V| <= this * l_max^3 is degenerate
  Metric worst_metric = Metric::MeanRatio;  // ranks the worst elements (signed: inverted first)
  int worst_count = 10;               // how many worst elements to list (>= 0)
  int histogram_bins = 10;            // bins per metric histogram (>= 1)
  double solver_tolerance = 1e-6;     // CG relative residual for the iteration estimate
  double poisson_ratio = 0.45;        // for the elasticity condition-number factor
};

inline constexpr std::array<double, 5> kReportPercentiles = {1, 5, 50, 95, 99};

struct Histogram {
  double lo = 0, hi = 0;             // bins split [lo, hi] evenly; hi falls in the last bin
  std::vector<std::size_t> counts;
  std::size_t below = 0, above = 0;  // values outside [lo, hi]
};

struct MetricStats {
  Metric metric = Metric::Volume;
  std::size_t count = 0;  // 0 for a mesh without tets (the numbers below are then 0)
  double min = 0, mean = 0, max = 0;
  // At kReportPercentiles, linear interpolation between order statistics (numpy default).
  std::array<double, 5> percentiles{};
  Histogram histogram;
};

struct WorstElement {
  TetId tet;
  int label = 0;
  TetQuality quality;
};

struct LabelStats {
  int label = 0;
  std::size_t tets = 0;
  double volume = 0;             // signed sum
  double min_dihedral = 0;       // degrees
  double mean_radius_ratio = 0;
  std::size_t inverted = 0, degenerate = 0, slivers = 0;
};

struct QualityReport {
  QualityOptions options;              // the options it was computed with
  std::size_t vertices = 0;            // live vertices
  std::size_t unreferenced_vertices = 0;  // live vertices in no tet
  std::size_t tets = 0;
  double total_volume = 0;             // signed sum
  Vec3 bbox_min = Vec3::Zero(), bbox_max = Vec3::Zero();  // of the live vertices
  double min_edge = 0, max_edge = 0;   // over the edges of all tets
  std::size_t inverted = 0, degenerate = 0, slivers = 0;
  std::vector<MetricStats> metrics;    // one per Metric, in enum order
  std::vector<WorstElement> worst;     // worst first, by options.worst_metric
  BoundaryTopology boundary;
  // The sharpest boundary edge (quality/boundary_angle.h): the worst dihedral angle no
  // surface-keeping improvement can lift above. Empty without manifold boundary edges.
  std::optional<BoundaryAngle> boundary_angle;
  // Slivers the surface forces: tets around a boundary edge whose interior angle is under
  // options.sliver_angle (quality/boundary_angle.h, sharp_boundary), which no mesh of this
  // surface lifts above it. The rest of `slivers` is what improvement could still reach.
  std::size_t forced_slivers = 0;
  // Of the other slivers, those across a part of the body thinner than a quarter of their
  // longest edge (quality/thin_parts.h): only smaller tets there would be better.
  std::size_t thin_slivers = 0;
  std::size_t components = 0;          // of tets through shared faces
  std::vector<LabelStats> labels;      // by increasing label
  SolverEstimate solver;

  const MetricStats& stats(Metric m) const { return metrics[static_cast<int>(m)]; }
};

// Throws InvalidArgument for out-of-range options. Positions: rest when empty, else indexed
// by VertexId (e.g. the deformed configuration).
QualityReport compute_quality_report(const TetMesh& mesh, const QualityOptions& options = {},
                                     std::span<const Vec3> positions = {});

// The report for people: compact aligned text, ~40 lines.
std::string format_quality_report(const QualityReport& report);

}  // namespace incise
