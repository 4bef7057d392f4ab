#pragma once
// Per-tet quality metrics (definitions and golden values: docs/quality-report.md).
//
// Every shape metric is normalized so that the regular tetrahedron scores exactly 1.
//  - Signed metrics (volume, radius_ratio, mean_ratio, volume_length, min_solid_angle)
//    carry the sign of the volume: 1 regular, 0 degenerate, < 0 inverted (the magnitude is
//    that of the mirror image). They lie in [-1, 1] (volume excepted).
//  - Dihedral angles are geometric (orientation-blind), in degrees in [0, 180].
//  - aspect_ratio and radius_edge are ratios >= 1 (larger is worse), orientation-blind,
//    clamped to kMaxRatio for degenerate tets so every value stays finite.
// Degenerate tets (flat, collinear, coincident points) give 0 for every signed shape
// metric, min_dihedral 0 and max_dihedral 180; no metric is ever NaN or infinite for finite
// input. Edges are formed by direct differences and rescaled by an exact power of two
// before anything else, so results do not depend on translation and hold from scale 1e-8
// to 1e8 and beyond (relative error ~1e-15 for well-shaped tets).
#include <array>
#include <span>
#include <string>
#include <string_view>

#include "mesh/tet_mesh.h"

namespace incise {

// Upper clamp of the ratio metrics (a tet that bad is degenerate by any useful threshold).
inline constexpr double kMaxRatio = 1e12;

struct TetQuality {
  double volume = 0;           // signed: > 0 for det(p1-p0, p2-p0, p3-p0) > 0
  double min_dihedral = 0;     // degrees; regular 70.53
  double max_dihedral = 180;   // degrees; regular 70.53
  double radius_ratio = 0;     // 3 r_in / R_circ, signed
  double mean_ratio = 0;       // 12 (3|V|)^(2/3) / sum l^2, signed
  double volume_length = 0;    // 6 sqrt(2) V / l_rms^3, signed
  double aspect_ratio = kMaxRatio;  // l_max / (2 sqrt(6) r_in), >= 1 (Verdict's definition)
  double min_solid_angle = 0;  // min vertex solid angle / acos(23/27), signed
  double radius_edge = kMaxRatio;   // (R_circ / l_min) / (sqrt(6)/4), >= 1
  double min_edge = 0;         // shortest edge length (not a metric; for the report)
  double max_edge = 0;         // longest edge length
};

// The metrics a report summarizes and ranks by, in report order.
enum class Metric {
  Volume,
  MinDihedral,
  MaxDihedral,
  RadiusRatio,
  MeanRatio,
  VolumeLength,
  AspectRatio,
  MinSolidAngle,
  RadiusEdge,
};
inline constexpr int kNumMetrics = 9;

struct MetricInfo {
  Metric metric;
  const char* name;       // snake_case, as in TetQuality and the JSON report
  const char* title;      // for people
  bool higher_is_better;  // worst elements are the smallest (true) or the largest (false)
  double hist_lo, hist_hi;  // histogram range; volume uses [0, max volume] instead
};
const MetricInfo& metric_info(Metric m);
std::span<const MetricInfo> all_metrics();
// Parses a metric name (as in MetricInfo::name); throws InvalidArgument listing the names.
Metric parse_metric(std::string_view name);
double metric_value(const TetQuality& q, Metric m);

// Quality of the tet (p0, p1, p2, p3).
TetQuality tet_quality(const Vec3& p0, const Vec3& p1, const Vec3& p2, const Vec3& p3);
// Quality of a live tet of `mesh`, at rest positions, or at `positions` (indexed by
// VertexId, e.g. the current deformed configuration) when that is not empty.
TetQuality tet_quality(const TetMesh& mesh, TetId t, std::span<const Vec3> positions = {});

// The extremes of a whole mesh (rest positions): what command summaries and benchmarks print.
struct QualityRange {
  double min_dihedral = 180, max_dihedral = 0, min_radius_ratio = 1;
  std::size_t below = 0;  // tets whose min dihedral is under `below_degrees`
};
QualityRange quality_range(const TetMesh& mesh, double below_degrees = 5.0);  // O(mesh)

}  // namespace incise
