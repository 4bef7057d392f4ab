#pragma once
// Internal to mesh/tetrahedralize (includes CGAL through its users): turns the cells of a
// Mesh_3 complex into a TetMesh. Not a public header.
#include <unordered_map>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "mesh/tet_mesh.h"
#include "mesh/tetrahedralize/tetrahedralize.h"

namespace incise::detail {

// Cells in the complex become tets (orientation fixed by the sign of the volume, the
// subdomain index becomes the label through `label_of`); boundary faces get kTagSurface;
// elements numbered along a space-filling curve (TetMesh::compact_spatially).
template <class C3t3, class LabelOf>
TetMesh c3t3_to_tet_mesh(const C3t3& c3t3, LabelOf label_of) {
  TetMesh mesh;
  mesh.reserve(c3t3.triangulation().number_of_vertices(), c3t3.number_of_cells_in_complex());
  std::unordered_map<typename C3t3::Vertex_handle, VertexId> ids;
  ids.reserve(c3t3.triangulation().number_of_vertices());
  auto vertex = [&](typename C3t3::Vertex_handle vh) {
    auto [it, fresh] = ids.try_emplace(vh, VertexId());
    if (fresh) {
      const auto& p = c3t3.triangulation().point(vh);
      it->second = mesh.add_vertex(Vec3(CGAL::to_double(p.x()), CGAL::to_double(p.y()), CGAL::to_double(p.z())));
    }
    return it->second;
  };
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
    std::array<VertexId, 4> v{vertex(c->vertex(0)), vertex(c->vertex(1)), vertex(c->vertex(2)), vertex(c->vertex(3))};
    const Vec3 &a = mesh.rest(v[0]), &b = mesh.rest(v[1]), &cc = mesh.rest(v[2]), &d = mesh.rest(v[3]);
    const double vol = (b - a).cross(cc - a).dot(d - a);
    if (vol < 0) std::swap(v[2], v[3]);
    if (vol == 0) throw Error("tetrahedralize: Mesh_3 produced a flat tet; try another --seed or size");
    mesh.add_tet(v[0], v[1], v[2], v[3], label_of(c3t3.subdomain_index(c)));
  }
  make_boundary_manifold(mesh);
  tag_boundary(mesh, kTagSurface);
  mesh.compact_spatially();  // the complex's order is scattered in space: solvers run faster in this one
  return mesh;
}

}  // namespace incise::detail
