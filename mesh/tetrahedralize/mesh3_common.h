#pragma once
// Internal to mesh/tetrahedralize: what the Mesh_3 translation units share (size
// resolution, the optimizer sequence, statistics). Not a public header; includes CGAL only
// through the .cpp files that include it after CGAL.
#include <chrono>
#include <cmath>
#include <iostream>
#include <sstream>

#include "mesh/errors.h"
#include "mesh/tetrahedralize/tetrahedralize.h"

namespace incise::detail {

inline double bbox_diagonal(const std::vector<Vec3>& pts) {
  if (pts.empty()) return 0;
  Eigen::AlignedBox3d box;
  for (const Vec3& p : pts) box.extend(p);
  return box.diagonal().norm();
}

struct Sizes {
  double size = 0;
  double facet_distance = 0;
  double edge_size = 0;
  double estimated_tets = 0;
};

// Resolves relative lengths against `diagonal` and refuses sizes that cannot give a useful
// mesh: larger than a quarter of the diagonal, or needing more than max_tets tets.
inline Sizes resolve_sizes(const TetraOptions& opt, double diagonal, double volume) {
  Sizes s;
  if (!(diagonal > 0) || !std::isfinite(diagonal)) throw InvalidArgument("tetrahedralize: the input has no extent");
  s.size = opt.size.resolve(diagonal);
  if (!(s.size > 0) || !std::isfinite(s.size))
    throw InvalidArgument("tetrahedralize: --size must be positive (got " + opt.size.str() + ")");
  if (s.size > diagonal / 4) {
    std::ostringstream os;
    os << "tetrahedralize: --size " << s.size << " is larger than the model allows (bounding-box diagonal "
       << diagonal << "; use at most " << diagonal / 4 << ", e.g. --size 3%)";
    throw InvalidArgument(os.str());
  }
  s.edge_size = opt.edge_size.value > 0 ? opt.edge_size.resolve(diagonal) : s.size;
  s.facet_distance = opt.facet_distance.value > 0 ? opt.facet_distance.resolve(diagonal) : s.size / 6;
  if (!(s.facet_distance > 0)) throw InvalidArgument("tetrahedralize: --facet-distance must be positive");
  if (opt.facet_angle <= 0 || opt.facet_angle > 30)
    throw InvalidArgument("tetrahedralize: --facet-angle must be in (0, 30] degrees (CGAL's termination bound)");
  if (opt.radius_edge < 2) throw InvalidArgument("tetrahedralize: --radius-edge must be >= 2 (CGAL's termination bound)");
  double min_size = s.size;
  for (const auto& [label, size] : opt.label_sizes) {
    if (!(size > 0)) throw InvalidArgument("tetrahedralize: --label-size " + std::to_string(label) + " must be positive");
    min_size = std::min(min_size, size);
  }
  s.estimated_tets = estimate_tet_count(volume, min_size);
  if (s.estimated_tets > double(opt.max_tets)) {
    std::ostringstream os;
    os << "tetrahedralize: size " << min_size << " would need about " << std::llround(s.estimated_tets)
       << " tets (volume " << volume << " / size^3), more than the limit of " << opt.max_tets
       << "; use a larger --size or raise --max-tets";
    throw InvalidArgument(os.str());
  }
  return s;
}

// Runs the optimizers `opt.optimize` asks for, in CGAL's order (ODT, Lloyd, perturb,
// exude). Mesh_3 guarantees a manifold boundary after refinement only: an optimizer step
// that breaks it (`boundary_ok` false) is undone from a copy and noted in `stats`.
template <class C3t3, class Domain, class BoundaryOk>
void optimize(C3t3& c3t3, const Domain& domain, const TetraOptions& opt, BoundaryOk boundary_ok, TetraStats& stats) {
  using namespace CGAL::parameters;
  auto step = [&](const char* name, auto&& run) {
    const auto t0 = std::chrono::steady_clock::now();
    if (opt.progress) std::cerr << "tetra: " << name << "...\n";
    C3t3 backup = c3t3;
    const CGAL::Mesh_optimization_return_code rc = run();
    if (rc == CGAL::TIME_LIMIT_REACHED) stats.time_limit_hit = true;
    const bool ok = boundary_ok(c3t3);
    if (!ok) {
      c3t3 = std::move(backup);
      stats.notes.push_back(std::string(name) + " undone (it made the boundary non-manifold)");
    }
    if (opt.progress)
      std::cerr << "tetra: " << name << " done in "
                << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s"
                << (rc == CGAL::TIME_LIMIT_REACHED ? " (time limit reached)" : "")
                << (ok ? "" : " (undone: it made the boundary non-manifold)") << "\n";
  };
  const double tl = opt.optimize_time;
  if (opt.optimize & kOptimizeOdt)
    step("ODT smoothing", [&] { return CGAL::odt_optimize_mesh_3(c3t3, domain, time_limit = tl, max_iteration_number = 20); });
  if (opt.optimize & kOptimizeLloyd)
    step("Lloyd smoothing", [&] { return CGAL::lloyd_optimize_mesh_3(c3t3, domain, time_limit = tl, max_iteration_number = 20); });
  if (opt.optimize & kOptimizePerturb)
    step("sliver perturbation", [&] { return CGAL::perturb_mesh_3(c3t3, domain, time_limit = tl, sliver_bound = opt.sliver_bound); });
  if (opt.optimize & kOptimizeExude)
    step("sliver exudation", [&] { return CGAL::exude_mesh_3(c3t3, time_limit = tl, sliver_bound = opt.sliver_bound); });
}

// Whether the complex converts to a TetMesh with a closed manifold boundary.
template <class C3t3, class Convert>
bool boundary_manifold(const C3t3& c3t3, Convert convert) {
  try {
    convert(c3t3).validate({true, true});
    return true;
  } catch (const Error&) {
    return false;
  }
}

inline void fill_stats(const TetMesh& mesh, std::chrono::steady_clock::time_point t0, double size, TetraStats& st) {
  st.tets = mesh.num_tets();
  st.vertices = mesh.num_vertices();
  auto [lo, hi] = dihedral_range(mesh);
  st.min_dihedral = lo;
  st.max_dihedral = hi;
  st.volume = mesh.total_volume();
  st.size = size;
  st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace incise::detail
