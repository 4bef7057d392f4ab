#include "mesh/generate.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "mesh/errors.h"
#include "mesh/memory_limit.h"

namespace incise {

void tag_boundary(TetMesh& mesh, std::uint16_t tag) {
  for (TetId t : mesh.tets())
    for (int f = 0; f < 4; ++f)
      if (!mesh.neighbor(t, f).is_valid()) mesh.set_face_tag(t, f, tag);
}

namespace {

// Lattice of (nx+1)(ny+1)(nz+1) points given by `pos(i,j,k)`, split into Kuhn tets. The
// orientation is decided on the undeformed lattice so a mapping that flips a tet shows up
// in validate() instead of being silently repaired. Mirrored: cubes with an odd index along an
// axis are reflected along it (their diagonals alternate; still conforming, see BoxSplit).
template <class Pos>
TetMesh kuhn_lattice(const std::array<int, 3>& n, Pos pos, int label, BoxSplit split = BoxSplit::Kuhn) {
  // The size before any work: ids are 32-bit, and the mesh must fit in memory.
  const double cells = double(n[0]) * n[1] * n[2], verts = (double(n[0]) + 1) * (double(n[1]) + 1) * (double(n[2]) + 1);
  const std::string what = std::to_string(n[0]) + "x" + std::to_string(n[1]) + "x" + std::to_string(n[2]) + " cells";
  if (6 * cells >= double(TetId::invalid_index) || verts >= double(VertexId::invalid_index))
    throw InvalidArgument(what + " make " + format_count(6 * cells) + " tets and " + format_count(verts) +
                          " vertices, more than a mesh's 32-bit ids can number; use fewer cells");
  refuse_past_memory(what, 6 * cells * kTetMeshBytesPerTet, format_count(6 * cells) + " tets", "use fewer cells");
  TetMesh m;
  const std::size_t nv = std::size_t(n[0] + 1) * (n[1] + 1) * (n[2] + 1);
  m.reserve(nv, 6 * std::size_t(n[0]) * n[1] * n[2]);
  auto id = [&](int i, int j, int k) {
    return VertexId(static_cast<std::uint32_t>((std::size_t(k) * (n[1] + 1) + j) * (n[0] + 1) + i));
  };
  for (int k = 0; k <= n[2]; ++k)
    for (int j = 0; j <= n[1]; ++j)
      for (int i = 0; i <= n[0]; ++i) m.add_vertex(pos(i, j, k));
  static const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (int k = 0; k < n[2]; ++k)
    for (int j = 0; j < n[1]; ++j)
      for (int i = 0; i < n[0]; ++i)
        for (const auto& p : perms) {
          const int base[3] = {i, j, k};
          const bool flip[3] = {split == BoxSplit::Mirrored && (i & 1), split == BoxSplit::Mirrored && (j & 1),
                                split == BoxSplit::Mirrored && (k & 1)};
          int l[3] = {0, 0, 0};  // the corner in the cube's own (possibly reflected) frame
          auto corner = [&] {
            int g[3];
            for (int d = 0; d < 3; ++d) g[d] = base[d] + (flip[d] ? 1 - l[d] : l[d]);
            return id(g[0], g[1], g[2]);
          };
          VertexId v[4];
          v[0] = corner();
          for (int s = 0; s < 3; ++s) {
            l[p[s]] = 1;
            v[s + 1] = corner();
          }
          // Parity of the permutation decides the orientation in the reference lattice, and each
          // reflection reverses it.
          bool odd = (p[0] == 0 && p[1] == 2) || (p[0] == 1 && p[1] == 0) || (p[0] == 2 && p[1] == 1);
          odd ^= flip[0] ^ flip[1] ^ flip[2];
          // Kuhn tet (0, e_p0, e_p0+e_p1, 1) has det = sign(permutation) (identity: +1).
          if (odd)
            m.add_tet(v[0], v[1], v[3], v[2], label);
          else
            m.add_tet(v[0], v[1], v[2], v[3], label);
        }
  tag_boundary(m);
  m.discard_change();
  return m;
}

}  // namespace

TetMesh make_box(const Vec3& size, const std::array<int, 3>& cells, int label, BoxSplit split) {
  for (int d = 0; d < 3; ++d) {
    if (!(size[d] > 0) || !std::isfinite(size[d])) throw InvalidArgument("make_box: sizes must be positive and finite");
    if (cells[d] < 1) throw InvalidArgument("make_box: cell counts must be at least 1");
  }
  Vec3 h(size[0] / cells[0], size[1] / cells[1], size[2] / cells[2]);
  // Sizes of 1e308 or 1e-308 are finite, but a cell's volume would overflow or vanish (the
  // mesh's volume then printed as -nan).
  if (const double v = h[0] * h[1] * h[2]; !(v > std::numeric_limits<double>::min()) || !std::isfinite(v * 6 * cells[0] * double(cells[1]) * cells[2]))
    throw InvalidArgument("make_box: the cells' volume is not a normal positive number (sizes too large or too small "
                          "for double precision)");
  return kuhn_lattice(cells, [&](int i, int j, int k) { return Vec3(i * h[0], j * h[1], k * h[2]); }, label, split);
}

TetMesh make_ellipsoid(const Vec3& radii, int n, int label) {
  for (int d = 0; d < 3; ++d)
    if (!(radii[d] > 0) || !std::isfinite(radii[d])) throw InvalidArgument("make_ellipsoid: radii must be positive and finite");
  if (n < 1) throw InvalidArgument("make_ellipsoid: resolution must be at least 1");
  const int m = 2 * n;
  return kuhn_lattice({m, m, m},
                      [&](int i, int j, int k) {
                        Vec3 q(-1.0 + 2.0 * i / m, -1.0 + 2.0 * j / m, -1.0 + 2.0 * k / m);
                        double linf = q.cwiseAbs().maxCoeff(), l2 = q.norm();
                        // Each cube shell |q|_inf = r maps onto the sphere of radius r.
                        Vec3 s = l2 > 0 ? Vec3(q * (linf / l2)) : Vec3::Zero();
                        return Vec3(s.cwiseProduct(radii));
                      },
                      label);
}

TetMesh make_tube(double inner, double outer, double height, double angle_deg, const std::array<int, 3>& cells,
                  int label) {
  auto finite_positive = [](double x) { return x > 0 && std::isfinite(x); };
  if (!finite_positive(inner) || !finite_positive(outer) || !(inner < outer))
    throw InvalidArgument("make_tube: radii must be finite with 0 < inner < outer");
  if (!finite_positive(height)) throw InvalidArgument("make_tube: height must be positive and finite");
  if (!(angle_deg > 0 && angle_deg < 360)) throw InvalidArgument("make_tube: angle must be in (0, 360) degrees");
  for (int c : cells)
    if (c < 1) throw InvalidArgument("make_tube: cell counts must be at least 1");
  const double angle = angle_deg * M_PI / 180;
  TetMesh m = kuhn_lattice(
      cells,
      [&](int i, int j, int k) {
        const double r = inner + (outer - inner) * i / cells[0], th = angle * j / cells[1];
        return Vec3(r * std::cos(th), r * std::sin(th), height * k / cells[2]);
      },
      label);
  // Wall faces: all three corners on the wall's radius (lattice points lie on it to rounding).
  const double tol = 1e-9 * outer;
  auto on_radius = [&](const std::array<VertexId, 3>& f, double r) {
    for (VertexId v : f)
      if (std::abs(m.rest(v).head<2>().norm() - r) > tol) return false;
    return true;
  };
  for (const BoundaryFace& f : m.boundary_faces()) {
    if (on_radius(f.vertices, inner)) m.set_face_tag(f.tet, f.local, kTagTubeInner);
    else if (on_radius(f.vertices, outer)) m.set_face_tag(f.tet, f.local, kTagTubeOuter);
  }
  return m;
}

TetMesh make_cook_membrane(int cells, double thickness, int label) {
  if (cells < 1) throw InvalidArgument("make_cook_membrane: cell count must be at least 1");
  if (!(thickness > 0) || !std::isfinite(thickness))
    throw InvalidArgument("make_cook_membrane: thickness must be positive and finite");
  const int n = cells;
  // x = 48 i / n; y between the bottom and top edges at that x (dy/dj > 0: orientation kept).
  TetMesh m = kuhn_lattice(
      {n, n, 1},
      [&](int i, int j, int k) {
        const double x = 48.0 * i / n, bottom = 44.0 * i / n, top = 44.0 + 16.0 * i / n;
        return Vec3(x, bottom + (top - bottom) * j / n, thickness * k);
      },
      label);
  // The edges' faces: all three corners on x = 0 or x = 48 (lattice values, exact).
  auto on_x = [&](const std::array<VertexId, 3>& f, double x) {
    for (VertexId v : f)
      if (m.rest(v).x() != x) return false;
    return true;
  };
  for (const BoundaryFace& f : m.boundary_faces()) {
    if (on_x(f.vertices, 0.0)) m.set_face_tag(f.tet, f.local, kTagCookClamped);
    else if (on_x(f.vertices, 48.0)) m.set_face_tag(f.tet, f.local, kTagCookLoaded);
  }
  return m;
}

}  // namespace incise
