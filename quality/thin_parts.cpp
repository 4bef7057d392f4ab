#include "quality/thin_parts.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "quality/metrics.h"

namespace incise {

std::vector<TetId> across_thin_parts(const TetMesh& mesh, std::span<const TetId> candidates,
                                     const ThinPartOptions& options) {
  // Outward unit normals of the boundary faces at each boundary vertex.
  IdMap<std::vector<Vec3>> normals;
  for (const BoundaryFace& f : mesh.boundary_faces()) {
    const Vec3 a = mesh.rest(f.vertices[0]);
    const Vec3 n = (mesh.rest(f.vertices[1]) - a).cross(mesh.rest(f.vertices[2]) - a);
    const double len = n.norm();
    if (!(len > 0)) continue;
    for (VertexId v : f.vertices) normals[v.idx()].push_back(n / len);
  }
  std::vector<TetId> out;
  if (normals.empty()) return out;
  for (TetId t : candidates) {
    const auto& v = mesh.tet_vertices(t);
    double longest = 0;
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) longest = std::max(longest, (mesh.rest(v[i]) - mesh.rest(v[j])).norm());
    const double limit = options.ratio * longest;
    bool thin = false;
    for (int i = 0; i < 4 && !thin; ++i) {
      const auto ni = normals.find(v[i].idx());
      if (ni == normals.end()) continue;
      for (int j = i + 1; j < 4 && !thin; ++j) {
        const auto nj = normals.find(v[j].idx());
        if (nj == normals.end()) continue;
        const Vec3 d = mesh.rest(v[i]) - mesh.rest(v[j]);
        for (const Vec3& a : ni->second)
          for (const Vec3& b : nj->second) {
            if (!(a.dot(b) < options.opposed_cos)) continue;
            // Across the part along the two sides' mean normal: v[i]'s side faces out along
            // m, v[j]'s against it, so the part lies between them where h > 0 (h < 0: the faces
            // face each other across a gap; h = 0: the two sides of a cut, the tet around its
            // front).
            const Vec3 m = (a - b).normalized();
            const double h = d.dot(m);
            if (h > 1e-6 * longest && h < limit) thin = true;
          }
      }
    }
    if (thin) out.push_back(t);
  }
  return out;
}

std::vector<TetId> slivers_across_thin_parts(const TetMesh& mesh, const ThinPartOptions& options,
                                             const std::vector<TetId>& exclude) {
  std::vector<TetId> slivers;
  for (TetId t : mesh.tets())
    if (!std::binary_search(exclude.begin(), exclude.end(), t) && tet_quality(mesh, t).min_dihedral < options.sliver_degrees)
      slivers.push_back(t);
  return across_thin_parts(mesh, slivers, options);
}

}  // namespace incise
