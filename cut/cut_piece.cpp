#include "cut/cut_piece.h"

#include <algorithm>
#include <cmath>

#include "cut/predicates.h"

namespace incise::cut_detail {

int Piece::side(const Vec3& x) const {
  return orient3d(plane.p[0], plane.p[1], plane.p[2], x);
}

std::array<double, 3> triangle_barycentric(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& x) {
  const Vec3 n = (b - a).cross(c - a);
  const double nn = n.squaredNorm();
  if (!(nn > 0)) return {-1, -1, -1};
  return {n.dot((b - x).cross(c - x)) / nn, n.dot((c - x).cross(a - x)) / nn, n.dot((a - x).cross(b - x)) / nn};
}

bool Piece::contains(const Vec3& x, double rel_tol) const {
  for (const CutTriangle& t : triangles) {
    const auto w = triangle_barycentric(t.p[0], t.p[1], t.p[2], x);
    if (w[0] >= -rel_tol && w[1] >= -rel_tol && w[2] >= -rel_tol) return true;
  }
  return false;
}

namespace {
double segment_distance(const std::array<Vec3, 2>& s, const Vec3& x) {
  const Vec3 e = s[1] - s[0];
  const double l2 = e.squaredNorm();
  const double u = l2 > 0 ? std::clamp(e.dot(x - s[0]) / l2, 0.0, 1.0) : 0.0;
  return (s[0] + u * e - x).norm();
}
}  // namespace

double Piece::boundary_distance(const Vec3& x) const {
  double d = 1e300;
  for (std::size_t i = 0; i < boundary.size(); ++i)
    if (rim[i]) d = std::min(d, segment_distance(boundary[i], x));
  return d;
}

namespace {
bool coplanar(const CutTriangle& t, const Vec3& x) {
  const Vec3 n = t.normal();
  const double scale = std::max({(t.p[1] - t.p[0]).norm(), (t.p[2] - t.p[0]).norm(), (x - t.p[0]).norm()});
  return std::abs(n.normalized().dot(x - t.p[0])) <= 1e-9 * scale;
}

}  // namespace

void finish_piece(Piece& p) {
  p.rim.assign(p.boundary.size(), true);
  p.plane = p.triangles[0];
  p.normal = p.plane.normal().normalized();
  p.lo = p.hi = p.triangles[0].p[0];
  for (const CutTriangle& t : p.triangles)
    for (const Vec3& x : t.p) {
      p.lo = p.lo.cwiseMin(x);
      p.hi = p.hi.cwiseMax(x);
    }
}

std::vector<Piece> make_pieces(std::span<const CutTriangle> triangles) {
  std::vector<Piece> out;
  std::size_t i = 0;
  while (i < triangles.size()) {
    const CutTriangle& t = triangles[i];
    // The swept quad: (a0,b0,b1) then (a0,b1,a1), sharing a0-b1.
    if (i + 1 < triangles.size()) {
      const CutTriangle& u = triangles[i + 1];
      if (u.p[0] == t.p[0] && u.p[1] == t.p[2] && coplanar(t, u.p[2]) && t.normal().dot(u.normal()) > 0) {
        Piece p;
        p.triangles = {t, u};
        p.boundary = {{t.p[0], t.p[1]}, {t.p[1], t.p[2]}, {u.p[1], u.p[2]}, {u.p[2], u.p[0]}};
        finish_piece(p);
        out.push_back(std::move(p));
        i += 2;
        continue;
      }
    }
    Piece p;
    p.triangles = {t};
    p.boundary = {{t.p[0], t.p[1]}, {t.p[1], t.p[2]}, {t.p[2], t.p[0]}};
    finish_piece(p);
    out.push_back(std::move(p));
    ++i;
  }
  // Segments two pieces share (the crease of a rotating blade) are inside the cut surface.
  for (std::size_t i = 0; i < out.size(); ++i)
    for (const auto& s : std::vector<std::array<Vec3, 2>>(out[i].boundary))
      for (std::size_t j = i + 1; j < out.size(); ++j)
        for (const auto& g : out[j].boundary)
          if ((s[0] == g[0] && s[1] == g[1]) || (s[0] == g[1] && s[1] == g[0])) mark_inner_segment(out, s[0], s[1]);
  return out;
}

void mark_inner_segment(std::vector<Piece>& pieces, const Vec3& a, const Vec3& b) {
  for (Piece& p : pieces)
    for (std::size_t i = 0; i < p.boundary.size(); ++i) {
      const auto& g = p.boundary[i];
      if ((a == g[0] && b == g[1]) || (a == g[1] && b == g[0])) p.rim[i] = false;
    }
}

bool tet_may_touch_triangle(const std::array<Vec3, 4>& tet, const CutTriangle& tri, double tol) {
  // Boxes.
  Vec3 tlo = tet[0], thi = tet[0], rlo = tri.p[0], rhi = tri.p[0];
  for (const Vec3& x : tet) {
    tlo = tlo.cwiseMin(x);
    thi = thi.cwiseMax(x);
  }
  for (const Vec3& x : tri.p) {
    rlo = rlo.cwiseMin(x);
    rhi = rhi.cwiseMax(x);
  }
  for (int k = 0; k < 3; ++k)
    if (tlo[k] > rhi[k] + tol || rlo[k] > thi[k] + tol) return false;
  // Triangle plane.
  const Vec3 n = tri.normal().normalized();
  double dmin = 1e300, dmax = -1e300;
  for (const Vec3& x : tet) {
    const double d = n.dot(x - tri.p[0]);
    dmin = std::min(dmin, d);
    dmax = std::max(dmax, d);
  }
  if (dmin > tol || dmax < -tol) return false;
  // Tet faces (outward normals of a positively oriented tet; an inverted current shape has no
  // outward side to test, so it stays a candidate).
  const double vol = (tet[1] - tet[0]).dot((tet[2] - tet[0]).cross(tet[3] - tet[0]));
  for (int f = 0; f < 4 && vol > 0; ++f) {
    const auto& l = kFaceLocal[f];
    const Vec3 fn = (tet[l[1]] - tet[l[0]]).cross(tet[l[2]] - tet[l[0]]);
    const double len = fn.norm();
    if (!(len > 0)) continue;
    const Vec3 u = fn / len;
    double m = 1e300;
    for (const Vec3& x : tri.p) m = std::min(m, u.dot(x - tet[l[0]]));
    if (m > tol) return false;
  }
  return true;
}

}  // namespace incise::cut_detail
