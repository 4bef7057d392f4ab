#pragma once
// Internal to mesh/tetrahedralize: what the Mesh_3 translation units share (size
// resolution, the optimizer sequence, statistics). Not a public header; includes CGAL only
// through the .cpp files that include it after CGAL.
#include <chrono>
#include <cmath>
#include <iostream>
#include <sstream>

#include "mesh/errors.h"
#include "mesh/memory_limit.h"
#include "mesh/tetrahedralize/tetrahedralize.h"

namespace incise::detail {

inline double bbox_diagonal(const std::vector<Vec3>& pts) {
  if (pts.empty()) return 0;
  Eigen::AlignedBox3d box;
  for (const Vec3& p : pts) box.extend(p);
  return box.diagonal().norm();
}

// What Mesh_3 holds per tet of its result (triangulation, complex, the image or surface
// domain): docs/tetra.md#size-limits.
constexpr double kMeshingBytesPerTet = 1100;

inline std::string fmt_length(double x) {
  std::ostringstream os;
  os << x;
  return os.str();
}

// Refuses an estimated tet count past --max-tets or past this machine's memory, naming it.
inline void check_estimate(const std::string& what, double tets, const std::string& how, const std::string& hint,
                           const TetraOptions& opt) {
  const std::string estimate = format_count(tets) + " tets";
  if (tets > double(opt.max_tets))
    throw InvalidArgument("tetrahedralize: " + what + " would need about " + estimate + " (" + how +
                          "), more than the limit of " + std::to_string(opt.max_tets) + "; " + hint +
                          " or raise --max-tets");
  refuse_past_memory("tetrahedralize: " + what, tets * kMeshingBytesPerTet, estimate, hint);
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
  check_estimate("size " + fmt_length(min_size), s.estimated_tets,
                 "volume " + fmt_length(volume) + " / size^3", "use a larger --size", opt);
  return s;
}

// The most vertices refinement may insert before it is stopped: a generous multiple of the
// estimate (criteria the estimate cannot see, a --facet-distance far below the size or a part
// thinner than it, ask for far more), bounded by --max-tets and the memory.
inline std::size_t refinement_vertex_limit(const TetraOptions& opt, double estimated_tets) {
  double tets = std::max(16 * estimated_tets, 1e6);
  tets = std::min(tets, double(opt.max_tets));
  if (const std::uint64_t have = available_memory_bytes()) tets = std::min(tets, double(have) / kMeshingBytesPerTet);
  return std::size_t(std::max(tets / 4, 1000.0));  // Delaunay meshes have 5-6 tets a vertex
}

struct RefinementLimitHit {};

// A Mesh_3 criterion that never calls a facet or cell bad but stops refinement (by throwing
// RefinementLimitHit) once the triangulation has more than `limit` vertices.
template <class Tr, class Visitor>
class VertexLimit : public CGAL::Mesh_3::Abstract_criterion<Tr, Visitor> {
  using Base = CGAL::Mesh_3::Abstract_criterion<Tr, Visitor>;

public:
  explicit VertexLimit(std::size_t limit) : limit_(limit) {}

protected:
  void do_accept(Visitor& v) const override { v.visit(*this); }
  Base* do_clone() const override { return new VertexLimit(*this); }
  typename Base::Is_bad do_is_bad(const Tr& tr, const typename Base::Handle&) const override {
    if (tr.number_of_vertices() > limit_) throw RefinementLimitHit{};
    return {};
  }

private:
  std::size_t limit_;
};

template <class Tr, class Criteria>
void limit_refinement(Criteria& criteria, std::size_t max_vertices) {
  criteria.add_facet_criterion(new VertexLimit<Tr, typename Criteria::Facet_criteria::Visitor>(max_vertices));
  criteria.add_cell_criterion(new VertexLimit<Tr, typename Criteria::Cell_criteria::Visitor>(max_vertices));
}

// make_mesh_3 under limit_refinement: a refinement stopped by the limit is an InvalidArgument
// that says which criteria to relax.
template <class Make>
auto refine_within(std::size_t max_vertices, const Sizes& sz, Make&& make) {
  try {
    return make();
  } catch (const RefinementLimitHit&) {
    std::ostringstream os;
    os << "tetrahedralize: refinement passed " << max_vertices << " vertices (about " << 5 * max_vertices
       << " tets, against ~" << std::llround(sz.estimated_tets) << " expected from the size) and was stopped: the"
       << " surface asks for far more than the size (facet distance " << sz.facet_distance << ", edge size "
       << sz.edge_size << ", or parts thinner than the size " << sz.size
       << "); use a larger --facet-distance or --edge-size (the limit is 16 times the size's estimate, at least"
       << " a million tets, at most --max-tets and the memory: a smaller --size raises it for thin parts)";
    throw InvalidArgument(os.str());
  }
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
