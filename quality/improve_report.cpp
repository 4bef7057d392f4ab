#include "quality/improve_report.h"

#include <cstdio>

namespace incise {

std::string format_improve_report(const ImproveReport& r) {
  char buf[800];
  std::snprintf(buf, sizeof buf,
                "improve: min dihedral %.2f -> %.2f deg, max dihedral %.2f -> %.2f deg, min radius ratio %.4f -> %.4f\n"
                "improve: %zu -> %zu tets; flips 2-3 %d, 3-2 %d, 4-4 %d, edge removals %d, multi-face %d, boundary %d "
                "(%d reshaping the surface); %d smoothing moves (%zu vertices, %d along feature lines); %d insertions "
                "(%d boundary)%s; %d contractions; %.2f s%s\n"
                "improve: label volumes moved by at most %.2g%%\n",
                r.min_dihedral_before, r.min_dihedral_after, r.max_dihedral_before, r.max_dihedral_after,
                r.min_radius_ratio_before, r.min_radius_ratio_after, r.tets_before, r.tets_after, r.flips23, r.flips32,
                r.flips44, r.edge_removals, r.multi_face_removals, r.boundary_flips, r.surface_flips, r.smoothing_moves,
                r.moved_vertices.size(), r.feature_slides, r.insertions, r.boundary_insertions,
                r.growth_capped ? ", stopped by the growth cap (--max-growth)" : "", r.contractions, r.seconds,
                r.budget_exhausted ? " (time or work limit reached)" : "",
                r.label_volume_change < 1e-12 ? 0.0 : 100 * r.label_volume_change);  // 0: kept up to rounding
  return buf;
}

nlohmann::json improve_report_json(const ImproveReport& r) {
  nlohmann::json j;
  j["schema"] = "incise.improve/1";
  j["before"] = {{"min_dihedral", r.min_dihedral_before},
                 {"max_dihedral", r.max_dihedral_before},
                 {"min_radius_ratio", r.min_radius_ratio_before},
                 {"tets", r.tets_before}};
  j["after"] = {{"min_dihedral", r.min_dihedral_after},
                {"max_dihedral", r.max_dihedral_after},
                {"min_radius_ratio", r.min_radius_ratio_after},
                {"tets", r.tets_after}};
  j["operations"] = {{"flips23", r.flips23},
                     {"flips32", r.flips32},
                     {"flips44", r.flips44},
                     {"edge_removals", r.edge_removals},
                     {"boundary_flips", r.boundary_flips},
                     {"multi_face_removals", r.multi_face_removals},
                     {"smoothing_moves", r.smoothing_moves},
                     {"insertions", r.insertions},
                     {"boundary_insertions", r.boundary_insertions},
                     {"contractions", r.contractions},
                     {"surface_flips", r.surface_flips},
                     {"feature_slides", r.feature_slides}};
  j["growth_capped"] = r.growth_capped;
  j["moved_vertices"] = r.moved_vertices.size();
  j["label_volume_change"] = r.label_volume_change;
  j["seconds"] = r.seconds;
  j["budget_exhausted"] = r.budget_exhausted;
  j["work"] = r.work;  // operations tried, as --max-work counts them
  return j;
}

}  // namespace incise
