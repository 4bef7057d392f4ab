// CGAL Mesh_3 on a closed triangle surface (Polyhedral_mesh_domain_with_features_3).
// The heavy translation unit: nothing else lives here.
#include <chrono>
#include <cmath>
#include <iostream>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polyhedral_mesh_domain_with_features_3.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/make_mesh_3.h>

#include "mesh/errors.h"
#include "mesh/tetrahedralize/c3t3_to_tet_mesh.h"
#include "mesh/tetrahedralize/mesh3_common.h"
#include "mesh/tetrahedralize/tetrahedralize.h"

namespace incise {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Polyhedron = CGAL::Surface_mesh<K::Point_3>;
using Domain = CGAL::Polyhedral_mesh_domain_with_features_3<K, Polyhedron>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr, Domain::Corner_index, Domain::Curve_index>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;

}  // namespace

TetMesh tetrahedralize_surface(const SurfaceMesh& surface, const TetraOptions& opt, TetraStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
  if (surface.triangles.empty()) throw InvalidArgument("tetrahedralize: the surface has no triangles");
  const double diag = detail::bbox_diagonal(surface.vertices);
  const double volume = std::abs(enclosed_volume(surface));
  const detail::Sizes sz = detail::resolve_sizes(opt, diag, volume);

  // Mesh_3 has absolute tolerances inside: mesh in normalized coordinates (centred, unit
  // diagonal) so the result does not depend on the model's scale or position.
  Eigen::AlignedBox3d box;
  for (const Vec3& p : surface.vertices) box.extend(p);
  const Vec3 center = box.center();
  std::vector<K::Point_3> points;
  points.reserve(surface.vertices.size());
  for (const Vec3& p : surface.vertices) {
    const Vec3 q = (p - center) / diag;
    points.emplace_back(q.x(), q.y(), q.z());
  }
  std::vector<std::array<std::size_t, 3>> polys;
  polys.reserve(surface.triangles.size());
  for (const auto& t : surface.triangles) polys.push_back({std::size_t(t[0]), std::size_t(t[1]), std::size_t(t[2])});
  if (!CGAL::Polygon_mesh_processing::is_polygon_soup_a_polygon_mesh(polys))
    throw InvalidArgument("tetrahedralize: the surface is not a manifold triangle mesh (use --repair)");
  Polyhedron poly;
  CGAL::Polygon_mesh_processing::polygon_soup_to_polygon_mesh(points, polys, poly);

  CGAL::Random rng(opt.seed);
  CGAL::get_default_random() = CGAL::Random(opt.seed);
  Domain domain(poly, &rng);
  const double features = opt.features_angle < 0 ? auto_features_angle(surface) : opt.features_angle;
  if (features > 0) {
    // Protecting balls about an edge size apart along every feature, each with its own
    // vertices and tets: counted before Mesh_3 places them (it cannot be stopped there).
    const double balls = feature_length(surface, features) / sz.edge_size;
    detail::check_estimate("edge size " + detail::fmt_length(sz.edge_size), 8 * balls,
                           detail::fmt_length(balls) + " protecting balls along the features", 
                           "use a larger --edge-size or --features 0", opt);
    domain.detect_features(features);
  }

  using namespace CGAL::parameters;
  Criteria criteria(edge_size = sz.edge_size / diag, facet_angle = opt.facet_angle, facet_size = sz.size / diag,
                    facet_distance = sz.facet_distance / diag, cell_radius_edge_ratio = opt.radius_edge,
                    cell_size = sz.size / diag);
  if (opt.progress)
    std::cerr << "tetra: Mesh_3 refinement (size " << sz.size << ", facet distance " << sz.facet_distance
              << ", ~" << static_cast<long long>(sz.estimated_tets) << " tets expected)\n";
  const std::size_t max_vertices = detail::refinement_vertex_limit(opt, sz.estimated_tets);
  detail::limit_refinement<Tr>(criteria, max_vertices);
  C3t3 c3t3 = detail::refine_within(max_vertices, sz, [&] {
    return CGAL::make_mesh_3<C3t3>(domain, criteria, no_perturb(), no_exude(), no_odt(), no_lloyd(), manifold());
  });
  TetraStats local;
  TetraStats& st = stats ? *stats : local;
  st = TetraStats{};
  auto convert = [](const C3t3& c) { return detail::c3t3_to_tet_mesh(c, [](int) { return 1; }); };
  detail::optimize(c3t3, domain, opt, [&](const C3t3& c) { return detail::boundary_manifold(c, convert); }, st);

  TetMesh mesh = convert(c3t3);
  for (VertexId v : mesh.vertices()) mesh.set_rest(v, mesh.rest(v) * diag + center);
  if (mesh.num_tets() == 0)
    throw Error("tetrahedralize: meshing produced no tets (is the surface closed? is --size too large?)");
  detail::fill_stats(mesh, t0, sz.size, st);
  st.input_volume = volume;
  st.engine = "cgal";
  st.features_angle = features;
  return mesh;
}

}  // namespace incise
