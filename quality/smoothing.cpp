#include "quality/smoothing.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

namespace incise {

namespace {

// How v may move: not at all, anywhere (interior), or within the plane through it with normal n.
struct Freedom {
  enum Kind { Fixed, Free, Plane } kind = Fixed;
  Vec3 n = Vec3::Zero();
  std::vector<std::array<VertexId, 3>> fan;  // boundary faces around v, rotated so v is first
};

Freedom freedom(const TetMesh& mesh, VertexId v, const ImproveScope& scope, const SmoothOptions& opt) {
  Freedom fr;
  if (opt.frozen && opt.frozen->count(v.idx())) return fr;
  const auto tets = mesh.incident_tets(v);
  if (tets.empty()) return fr;
  std::uint16_t tag = 0;
  bool first = true;
  for (TetId t : tets) {
    if (!scope.contains(t) || mesh.label(t) != mesh.label(tets.front())) return fr;
    const int lv = mesh.local_index(t, v);
    for (int f = 0; f < 4; ++f) {
      if (f == lv || mesh.neighbor(t, f).is_valid()) continue;
      if (!first && mesh.face_tag(t, f) != tag) return fr;  // v is where two tags meet
      tag = mesh.face_tag(t, f);
      first = false;
      auto fv = mesh.face_vertices(t, f);
      while (fv[0] != v) std::rotate(fv.begin(), fv.begin() + 1, fv.end());
      fr.fan.push_back(fv);
    }
  }
  if (fr.fan.empty()) {
    fr.kind = Freedom::Free;
    return fr;
  }
  if (tag == kTagCut ? !opt.move_cut : !opt.move_surface) return fr;
  // One disc: following x -> y around v visits every face once.
  std::map<std::uint32_t, VertexId> next;
  for (const auto& f : fr.fan)
    if (!next.emplace(f[1].idx(), f[2]).second) return fr;
  VertexId w = fr.fan.front()[1];
  for (std::size_t k = 0; k < fr.fan.size(); ++k) {
    auto it = next.find(w.idx());
    if (it == next.end()) return fr;
    w = it->second;
  }
  if (w != fr.fan.front()[1]) return fr;
  // Flat: every fan vertex within a tiny fraction of the fan's size from v's plane.
  const Vec3& pv = mesh.rest(v);
  Vec3 n = Vec3::Zero();
  double h = 0;
  for (const auto& f : fr.fan) {
    n += (mesh.rest(f[1]) - pv).cross(mesh.rest(f[2]) - pv);
    h = std::max(h, (mesh.rest(f[1]) - pv).norm());
  }
  if (!(n.norm() > 0)) return fr;
  n.normalize();
  for (const auto& f : fr.fan) {
    if (std::abs(n.dot(mesh.rest(f[1]) - pv)) > 1e-10 * h) return fr;
    if (!(n.dot((mesh.rest(f[1]) - pv).cross(mesh.rest(f[2]) - pv)) > 0)) return fr;
  }
  fr.kind = Freedom::Plane;
  fr.n = n;
  return fr;
}

// The incident tets with v's slot open.
struct Star {
  std::vector<std::array<Vec3, 4>> tets;
  std::vector<int> slot;
  AngleQuality at(const Vec3& p, const AngleTargets& t) const {
    AngleQuality w;
    for (std::size_t i = 0; i < tets.size(); ++i) w.combine(one(i, p, t));
    return w;
  }
  AngleQuality one(std::size_t i, const Vec3& p, const AngleTargets& t) const {
    auto x = tets[i];
    x[slot[i]] = p;
    return angle_quality(x[0], x[1], x[2], x[3], t);
  }
};

// Smallest vector in the convex hull of g (Frank-Wolfe; the hull is small).
Vec3 min_norm_in_hull(const std::vector<Vec3>& g) {
  Vec3 x = g.front();
  for (int it = 0; it < 64; ++it) {
    std::size_t best = 0;
    for (std::size_t i = 1; i < g.size(); ++i)
      if (g[i].dot(x) < g[best].dot(x)) best = i;
    const Vec3 d = g[best] - x;
    const double dd = d.squaredNorm();
    if (dd == 0 || x.dot(x) - g[best].dot(x) <= 1e-12 * x.squaredNorm()) break;
    x += std::clamp(-x.dot(d) / dd, 0.0, 1.0) * d;
  }
  return x;
}

// Barycentric parents of p (a point of v's star, or of its flat fan) for move_vertex.
bool locate(const TetMesh& mesh, VertexId v, const Vec3& p, const Freedom& fr, std::vector<VertexId>& parents,
            std::vector<double>& weights) {
  double best = -1e300;
  const Vec3& pv = mesh.rest(v);
  if (fr.kind == Freedom::Plane) {
    for (const auto& f : fr.fan) {
      const Vec3 x = mesh.rest(f[1]) - pv, y = mesh.rest(f[2]) - pv, q = p - pv;
      const double area = fr.n.dot(x.cross(y));
      const double lx = fr.n.dot(q.cross(y)) / area, ly = fr.n.dot(x.cross(q)) / area;
      const double m = std::min({1 - lx - ly, lx, ly});
      if (m > best) {
        best = m;
        parents.assign(f.begin(), f.end());
        weights = {1 - lx - ly, lx, ly};
      }
    }
  } else {
    for (TetId t : mesh.incident_tets(v)) {
      const auto& tv = mesh.tet_vertices(t);
      Eigen::Matrix3d a;
      for (int k = 0; k < 3; ++k) a.col(k) = mesh.rest(tv[k + 1]) - mesh.rest(tv[0]);
      const Vec3 l = a.partialPivLu().solve(p - mesh.rest(tv[0]));
      const double w[4] = {1 - l.sum(), l[0], l[1], l[2]};
      const double m = std::min({w[0], w[1], w[2], w[3]});
      if (m > best) {
        best = m;
        parents.assign(tv.begin(), tv.end());
        weights.assign(w, w + 4);
      }
    }
  }
  if (!(best > -1e-9)) return false;
  double s = 0;
  for (double& w : weights) s += (w = std::max(w, 0.0));
  for (double& w : weights) w /= s;
  return true;
}

}  // namespace

bool smooth_vertex(TetMesh& mesh, VertexId v, const ImproveScope& scope, const SmoothOptions& opt) {
  const Freedom fr = freedom(mesh, v, scope, opt);
  if (fr.kind == Freedom::Fixed) return false;
  Star star;
  double hmin = 1e300;
  for (TetId t : mesh.incident_tets(v)) {
    const auto& tv = mesh.tet_vertices(t);
    std::array<Vec3, 4> x;
    for (int k = 0; k < 4; ++k) {
      x[k] = mesh.rest(tv[k]);
      if (tv[k] != v) hmin = std::min(hmin, (x[k] - mesh.rest(v)).norm());
    }
    star.tets.push_back(x);
    star.slot.push_back(mesh.local_index(t, v));
  }
  const AngleTargets& tg = scope.targets;
  const Vec3 p0 = mesh.rest(v);
  const AngleQuality orig = star.at(p0, tg);
  Vec3 p = p0, best_p = p0;
  AngleQuality cur = orig;
  const double fd = 1e-6 * hmin;
  for (int it = 0; it < opt.iterations; ++it) {
    std::vector<Vec3> grads;
    for (std::size_t i = 0; i < star.tets.size(); ++i) {
      if (star.one(i, p, tg).q > cur.q + 1e-3) continue;  // not active
      Vec3 g;
      for (int k = 0; k < 3; ++k) {
        Vec3 e = Vec3::Zero();
        e[k] = fd;
        g[k] = (star.one(i, p + e, tg).q - star.one(i, p - e, tg).q) / (2 * fd);
      }
      if (fr.kind == Freedom::Plane) g -= fr.n * fr.n.dot(g);
      grads.push_back(g);
    }
    const Vec3 d = min_norm_in_hull(grads);
    if (!(d.norm() * hmin > 1e-9)) break;  // a (nonsmooth) local maximum
    bool stepped = false;
    for (double len = 0.3 * hmin; len > 1e-6 * hmin; len *= 0.5) {
      Vec3 trial = p + len * d.normalized();
      if (fr.kind == Freedom::Plane) trial -= fr.n * fr.n.dot(trial - p0);
      const AngleQuality q = star.at(trial, tg);
      if (q.q > cur.q) {
        p = trial;
        cur = q;
        stepped = true;
        break;
      }
    }
    if (!stepped) break;
    if (better(cur, orig)) best_p = p;
  }
  if (best_p == p0) return false;
  std::vector<VertexId> parents;
  std::vector<double> weights;
  if (!locate(mesh, v, best_p, fr, parents, weights)) return false;
  Vec3 actual = Vec3::Zero();  // exactly what move_vertex will compute
  for (std::size_t k = 0; k < parents.size(); ++k) actual += weights[k] * mesh.rest(parents[k]);
  if (!better(star.at(actual, tg), orig) || !mesh.is_move_ok(v, actual)) return false;
  mesh.move_vertex(v, parents, weights);
  return true;
}

}  // namespace incise
