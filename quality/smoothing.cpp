#include "quality/smoothing.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include "quality/star_ascent.h"

namespace incise {

namespace {

// How v may move: not at all, anywhere (interior), within the plane through it with normal
// n, or on the old curved disc `fan` (moving along n's tangent plane, projected back).
struct Freedom {
  enum Kind { Fixed, Free, Plane, Surface } kind = Fixed;
  Vec3 n = Vec3::Zero();
  std::vector<std::array<VertexId, 3>> fan;  // disc faces around v, v first, consistently oriented
};

// The faces around v that constrain it: boundary faces (one tag) or, inside the mesh, the
// faces between exactly two labels. Returns false when v is where constraints meet.
bool constraint_faces(const TetMesh& mesh, VertexId v, const ImproveScope& scope, const SmoothOptions& opt,
                      std::vector<std::array<VertexId, 3>>& fan, bool& cut) {
  const auto tets = mesh.incident_tets(v);
  const int la = mesh.label(tets.front());
  int lb = la;
  for (TetId t : tets) {
    if (!scope.contains(t)) return false;
    if (mesh.label(t) == la) continue;
    if (lb != la && mesh.label(t) != lb) return false;  // three labels meet
    lb = mesh.label(t);
  }
  std::vector<std::array<VertexId, 3>> boundary, interface;
  bool first = true;
  std::uint16_t tag = 0;
  for (TetId t : tets) {
    const int lv = mesh.local_index(t, v);
    for (int f = 0; f < 4; ++f) {
      if (f == lv) continue;
      const TetId u = mesh.neighbor(t, f);
      auto fv = mesh.face_vertices(t, f);
      while (fv[0] != v) std::rotate(fv.begin(), fv.begin() + 1, fv.end());
      if (!u.is_valid()) {
        if (!first && mesh.face_tag(t, f) != tag) return false;  // two tags meet at v
        tag = mesh.face_tag(t, f);
        first = false;
        boundary.push_back(fv);
      } else if (mesh.label(t) == la && mesh.label(u) != la) {
        interface.push_back(fv);  // oriented out of label la
      }
    }
  }
  if (!boundary.empty() && !interface.empty()) return false;  // boundary meets interface
  cut = tag == kTagCut;
  if (!boundary.empty() && (cut ? !opt.move_cut : !opt.move_surface)) return false;
  if (!interface.empty() && !opt.move_interface) return false;
  fan = boundary.empty() ? std::move(interface) : std::move(boundary);
  return true;
}

Freedom freedom(const TetMesh& mesh, VertexId v, const ImproveScope& scope, const SmoothOptions& opt) {
  Freedom fr;
  if (opt.frozen && opt.frozen->count(v.idx())) return fr;
  if (mesh.incident_tets(v).empty()) return fr;
  bool cut = false;
  if (!constraint_faces(mesh, v, scope, opt, fr.fan, cut)) return fr;
  if (fr.fan.empty()) {
    fr.kind = Freedom::Free;
    return fr;
  }
  // One disc: following x -> y around v visits every face once.
  std::map<std::uint32_t, std::size_t> from;
  for (std::size_t i = 0; i < fr.fan.size(); ++i)
    if (!from.emplace(fr.fan[i][1].idx(), i).second) return fr;
  std::size_t at = 0;
  for (std::size_t k = 0; k < fr.fan.size(); ++k) {
    auto it = from.find(fr.fan[at][2].idx());
    if (it == from.end()) return fr;
    at = it->second;
  }
  if (at != 0) return fr;
  const Vec3& pv = mesh.rest(v);
  std::vector<Vec3> normals;
  Vec3 n = Vec3::Zero();
  double h = 0;
  for (const auto& f : fr.fan) {
    normals.push_back((mesh.rest(f[1]) - pv).cross(mesh.rest(f[2]) - pv));
    n += normals.back();
    h = std::max(h, (mesh.rest(f[1]) - pv).norm());
  }
  if (!(n.norm() > 0)) return fr;
  n.normalize();
  fr.n = n;
  // Flat: every fan vertex within a tiny fraction of the fan's size from v's plane.
  bool flat = true;
  for (const auto& f : fr.fan) flat = flat && std::abs(n.dot(mesh.rest(f[1]) - pv)) <= 1e-10 * h;
  // Every face must project onto the tangent plane with its orientation (a height field).
  for (const Vec3& fn : normals)
    if (!(n.dot(fn) > 0.2 * fn.norm())) return fr;
  if (flat) {
    fr.kind = Freedom::Plane;
    return fr;
  }
  if (!opt.slide_curved || cut || (opt.curved_slid && opt.curved_slid->count(v.idx()))) return fr;
  // Smooth: adjacent faces (sharing edge v-y) bend by at most the feature angle.
  const double cos_feature = std::cos(opt.feature_angle_deg * 3.14159265358979323846 / 180);
  for (std::size_t i = 0; i < fr.fan.size(); ++i) {
    const std::size_t j = from.at(fr.fan[i][2].idx());
    if (normals[i].normalized().dot(normals[j].normalized()) < cos_feature) return fr;
  }
  fr.kind = Freedom::Surface;
  return fr;
}

// Barycentric parents of p (a point of v's star, or of its flat fan) for move_vertex.
bool locate(const TetMesh& mesh, VertexId v, const Vec3& p, const Freedom& fr, std::vector<VertexId>& parents,
            std::vector<double>& weights) {
  double best = -1e300;
  const Vec3& pv = mesh.rest(v);
  if (fr.kind == Freedom::Plane || fr.kind == Freedom::Surface) {
    // Barycentrics of p's projection along n onto each old disc face.
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

// Exactly what move_vertex computes from parents and weights.
Vec3 combine(const TetMesh& mesh, const std::vector<VertexId>& parents, const std::vector<double>& weights) {
  Vec3 p = Vec3::Zero();
  for (std::size_t k = 0; k < parents.size(); ++k) p += weights[k] * mesh.rest(parents[k]);
  return p;
}

// The point a constrained vertex can take for the wanted p (on its plane or old disc).
bool place(const TetMesh& mesh, VertexId v, const Vec3& p, const Freedom& fr, Vec3& out) {
  std::vector<VertexId> parents;
  std::vector<double> weights;
  if (!locate(mesh, v, p, fr, parents, weights)) return false;
  out = combine(mesh, parents, weights);
  return true;
}

}  // namespace

bool smooth_vertex(TetMesh& mesh, VertexId v, const ImproveScope& scope, const SmoothOptions& opt) {
  const Freedom fr = freedom(mesh, v, scope, opt);
  if (fr.kind == Freedom::Fixed) return false;
  OpenStar star;
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
  AscentOptions ao;
  ao.iterations = opt.iterations;
  ao.scale = hmin;
  if (fr.kind != Freedom::Free) {
    ao.normal = &fr.n;
    ao.project = [&](Vec3& p) { return place(mesh, v, p, fr, p); };
  }
  const Vec3 best_p = ascend(star, p0, tg, ao);
  if (best_p == p0) return false;
  std::vector<VertexId> parents;
  std::vector<double> weights;
  if (!locate(mesh, v, best_p, fr, parents, weights)) return false;
  const Vec3 actual = combine(mesh, parents, weights);
  if (!better(star.at(actual, tg), orig, tg) || !mesh.is_move_ok(v, actual)) return false;
  mesh.move_vertex(v, parents, weights);
  if (fr.kind == Freedom::Surface && opt.curved_slid) opt.curved_slid->insert(v.idx());
  return true;
}

}  // namespace incise
