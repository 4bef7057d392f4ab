// CGAL Mesh_3 on a labeled 3D image (Labeled_mesh_domain_3). The other heavy translation
// unit.
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <set>

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Image_3.h>
#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_constant_domain_field_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/make_mesh_3.h>

#include "mesh/io/input_file.h"
#include "mesh/errors.h"
#include "mesh/tetrahedralize/c3t3_to_tet_mesh.h"
#include "mesh/tetrahedralize/mesh3_common.h"
#include "mesh/tetrahedralize/tetrahedralize.h"

namespace incise {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Domain = CGAL::Labeled_mesh_domain_3<K>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;
using SizingField = CGAL::Mesh_constant_domain_field_3<Domain::R, Domain::Index>;

}  // namespace

TetMesh tetrahedralize_image(const std::string& path, const TetraOptions& opt, TetraStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
  check_input_file(path);
  CGAL::Image_3 image;
  if (!image.read(path)) throw IoError(path, 0, "cannot read the image (CGAL Image_3: .inr, .inr.gz, Analyze, GIS)");
  if (image.xdim() == 0 || image.ydim() == 0 || image.zdim() == 0) throw IoError(path, 0, "empty image");

  // Labels present (nonzero) and the labelled volume, for the size checks.
  std::map<int, std::size_t> counts;
  for (std::size_t k = 0; k < image.zdim(); ++k)
    for (std::size_t j = 0; j < image.ydim(); ++j)
      for (std::size_t i = 0; i < image.xdim(); ++i) {
        const int label = static_cast<int>(std::lround(image.value(i, j, k)));
        if (label != 0) ++counts[label];
      }
  if (counts.empty()) throw IoError(path, 0, "the image has no nonzero label: nothing to mesh");
  const double voxel_volume = image.vx() * image.vy() * image.vz();
  std::size_t labelled = 0;
  for (auto& [l, c] : counts) labelled += c;
  const double volume = double(labelled) * voxel_volume;
  const double diag = Vec3(image.xdim() * image.vx(), image.ydim() * image.vy(), image.zdim() * image.vz()).norm();
  for (const auto& [label, size] : opt.label_sizes)
    if (!counts.count(label))
      throw InvalidArgument("tetrahedralize: --label-size " + std::to_string(label) + ": no such label in " + path);
  const detail::Sizes sz = detail::resolve_sizes(opt, diag, volume);
  if (opt.progress) {
    std::cerr << "tetra: image " << image.xdim() << "x" << image.ydim() << "x" << image.zdim() << ", voxel "
              << image.vx() << "x" << image.vy() << "x" << image.vz() << ", labels";
    for (auto& [l, c] : counts) std::cerr << " " << l << " (" << c << " voxels)";
    std::cerr << "\n";
  }

  // Labels with a handful of voxels (segmentation noise: the liver sample has a 2-voxel
  // label) cannot be meshed at any useful size and only slow refinement down: they are
  // treated as outside, with a message.
  std::set<int> dropped;
  const std::size_t tiny = std::max<std::size_t>(8, labelled / 10000);
  for (auto& [l, c] : counts)
    if (c < tiny && !opt.label_sizes.count(l)) dropped.insert(l);
  if (!dropped.empty() && opt.progress) {
    std::cerr << "tetra: labels treated as outside (fewer than " << tiny << " voxels):";
    for (int l : dropped) std::cerr << " " << l;
    std::cerr << "\n";
  }

  CGAL::Random rng(opt.seed);
  CGAL::get_default_random() = CGAL::Random(opt.seed);
  Domain domain = Domain::create_labeled_image_mesh_domain(image, CGAL::parameters::relative_error_bound = 1e-3,
                                                           CGAL::parameters::p_rng = &rng,
                                                           CGAL::parameters::image_values_to_subdomain_indices =
                                                               [dropped](double v) {
                                                                 const int l = static_cast<int>(std::lround(v));
                                                                 return dropped.count(l) ? 0 : l;
                                                               });
  SizingField sizing(sz.size);
  for (const auto& [label, size] : opt.label_sizes) sizing.set_size(size, 3, domain.index_from_subdomain_index(label));

  using namespace CGAL::parameters;
  Criteria criteria(facet_angle = opt.facet_angle, facet_size = sz.size, facet_distance = sz.facet_distance,
                    cell_radius_edge_ratio = opt.radius_edge, cell_size = sizing);
  if (opt.progress)
    std::cerr << "tetra: Mesh_3 refinement (size " << sz.size << ", facet distance " << sz.facet_distance << ", ~"
              << static_cast<long long>(sz.estimated_tets) << " tets expected)\n";
  // No manifold(): the facet complex of a multi-label image includes the interfaces, which
  // are non-manifold at every triple junction, so refinement would never end. The outer
  // boundary is made manifold afterwards (make_boundary_manifold).
  const std::size_t max_vertices = detail::refinement_vertex_limit(opt, sz.estimated_tets);
  detail::limit_refinement<Tr>(criteria, max_vertices);
  C3t3 c3t3 = detail::refine_within(max_vertices, sz, [&] {
    return CGAL::make_mesh_3<C3t3>(domain, criteria, no_perturb(), no_exude(), no_odt(), no_lloyd());
  });
  TetraStats local;
  TetraStats& st = stats ? *stats : local;
  st = TetraStats{};
  auto convert = [](const C3t3& c) { return detail::c3t3_to_tet_mesh(c, [](auto index) { return static_cast<int>(index); }); };
  detail::optimize(c3t3, domain, opt, [&](const C3t3& c) { return detail::boundary_manifold(c, convert); }, st);

  TetMesh mesh = convert(c3t3);
  if (mesh.num_tets() == 0) throw Error("tetrahedralize: meshing " + path + " produced no tets (is --size too large?)");
  detail::fill_stats(mesh, t0, sz.size, st);
  st.input_volume = volume;
  st.engine = "cgal";
  return mesh;
}

}  // namespace incise
