#include "quality/smoothing.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <vector>

#include "mesh/point_locator.h"
#include "quality/star_ascent.h"

namespace incise {

namespace {

// How v may move: not at all, anywhere (interior), within the plane through it with normal
// n, on the old curved disc `fan` (moving along n's tangent plane, projected back), or along
// a straight crease of the boundary (direction n) between its crease neighbours a and b.
struct Freedom {
  enum Kind { Fixed, Free, Plane, Surface, Line, Bent, Front } kind = Fixed;
  Vec3 n = Vec3::Zero();
  std::vector<std::array<VertexId, 3>> fan;  // disc faces around v, v first, consistently oriented
  std::vector<std::uint16_t> tags;           // per fan face (boundary fans)
  VertexId a, b;                             // Line: the crease neighbours (a - v opposite to n)
                                             // Bent, Front: the line's neighbours; n points from a's side to b's
  bool a_open = true, b_open = true;         // Bent, Front: whether v may move towards a (b)
};

int slides_of(const IdMap<int>& slides, VertexId v) {
  const auto it = slides.find(v.idx());
  return it == slides.end() ? 0 : it->second;
}

// v slides along the old segments v-a and v-b (unit directions ua, ub) of a bent line, exactly
// on the input's line: only where the pass found it (it never slid along a line or a curved
// part), and only towards a neighbour that never did either, so the segment it moves on is a
// piece of an input segment (a neighbour that slid may have left the corner between them).
bool along_line(const SmoothOptions& opt, VertexId v, VertexId a, VertexId b, const Vec3& ua, const Vec3& ub,
                Freedom::Kind kind, Freedom& fr) {
  if (!((ub - ua).norm() > 0)) return false;
  if (opt.curved_slides) {
    if (slides_of(*opt.curved_slides, v) > 0) return false;
    fr.a_open = slides_of(*opt.curved_slides, a) == 0;
    fr.b_open = slides_of(*opt.curved_slides, b) == 0;
    if (!fr.a_open && !fr.b_open) return false;
  }
  fr.kind = kind;
  fr.a = a;
  fr.b = b;
  fr.n = (ub - ua).normalized();
  return true;
}

// A feature line bent at v: exactly two of v's fan edges (v,a), (v,b) are features (tags
// change across them or their faces bend more than the feature angle), every other edge is
// smooth, and the line a-v-b bends by at most the line angle. v may slide along the old
// segments v-a and v-b: the feature stays on its old polyline and the faces beside it move
// by their sagitta (the caller spends the volume that moves).
bool feature_line(const TetMesh& mesh, VertexId v, const std::vector<Vec3>& normals,
                  const std::map<std::uint32_t, std::size_t>& from, const SmoothOptions& opt, Freedom& fr) {
  const double cos_feature = std::cos(opt.feature_angle_deg * 3.14159265358979323846 / 180);
  std::vector<VertexId> feature;
  for (std::size_t i = 0; i < fr.fan.size(); ++i) {
    const std::size_t j = from.at(fr.fan[i][2].idx());  // the face across edge (v, fan[i][2])
    const bool bent = normals[i].normalized().dot(normals[j].normalized()) < cos_feature;
    if (bent || fr.tags[i] != fr.tags[j]) feature.push_back(fr.fan[i][2]);
  }
  if (feature.size() != 2) return false;
  const Vec3& pv = mesh.rest(v);
  const Vec3 ua = (mesh.rest(feature[0]) - pv).normalized(), ub = (mesh.rest(feature[1]) - pv).normalized();
  // The line's bend at v: 180 degrees minus the angle a-v-b.
  if (-ua.dot(ub) < std::cos(opt.feature_line_angle_deg * 3.14159265358979323846 / 180)) return false;
  return along_line(opt, v, feature[0], feature[1], ua, ub, Freedom::Bent, fr);
}

// v's fan by its edges: neighbour w -> the fan faces holding the edge (v, w).
std::map<std::uint32_t, std::vector<std::size_t>> fan_edges(const Freedom& fr) {
  std::map<std::uint32_t, std::vector<std::size_t>> at_edge;
  for (std::size_t i = 0; i < fr.fan.size(); ++i)
    for (int k = 1; k < 3; ++k) at_edge[fr.fan[i][k].idx()].push_back(i);
  return at_edge;
}

// Every face of v's disc in one plane, some facing each way (a disc folded onto itself, as
// the two sides of a cut are around its front): every face's normal parallel to the first
// one's, to a tiny angle (each face holds v, so each lies in the plane through v).
bool folded_flat(const std::vector<Vec3>& normals) {
  const Vec3 n0 = normals.front().normalized();
  bool up = false, down = false;
  for (const Vec3& fn : normals) {
    const double c = n0.dot(fn);
    if (!(std::abs(c) > 0) || n0.cross(fn).norm() > 1e-10 * fn.norm()) return false;
    (c > 0 ? up : down) = true;
  }
  return up && down;
}

// A cut's front bent at v within the cut's plane: v's disc, folded flat (folded_flat), folds
// along exactly two edges (v,a), (v,b), where the faces on either side face opposite ways. v
// slides along the old segments v-a and v-b (along_line).
bool front_line(const TetMesh& mesh, VertexId v, const std::vector<Vec3>& normals, const SmoothOptions& opt,
                Freedom& fr) {
  const auto at_edge = fan_edges(fr);
  std::vector<VertexId> front;
  for (const auto& [w, faces] : at_edge) {
    if (faces.size() != 2) return false;
    if (normals[faces[0]].dot(normals[faces[1]]) < 0) front.push_back(VertexId(w));
  }
  if (front.size() != 2) return false;
  const Vec3& pv = mesh.rest(v);
  const Vec3 ua = (mesh.rest(front[0]) - pv).normalized(), ub = (mesh.rest(front[1]) - pv).normalized();
  return along_line(opt, v, front[0], front[1], ua, ub, Freedom::Front, fr);
}

// A straight crease through v: exactly two of v's boundary edges (v,a), (v,b) separate faces
// that differ in tag or plane, a and b lie on opposite sides of v on one line, and the faces
// between them are coplanar on each side. Sliding along it keeps both sides' planes.
bool crease_line(const TetMesh& mesh, VertexId v, Freedom& fr) {
  const auto at_edge = fan_edges(fr);
  const Vec3& pv = mesh.rest(v);
  auto normal = [&](std::size_t i) { return (mesh.rest(fr.fan[i][1]) - pv).cross(mesh.rest(fr.fan[i][2]) - pv); };
  std::vector<VertexId> crease;
  for (const auto& [w, faces] : at_edge) {
    if (faces.size() != 2) return false;  // not one disc around v
    const Vec3 n0 = normal(faces[0]), n1 = normal(faces[1]);
    const bool coplanar = n0.dot(n1) > 0 && n0.cross(n1).norm() <= 1e-10 * n0.norm() * n1.norm();
    if (fr.tags[faces[0]] != fr.tags[faces[1]] || !coplanar) crease.push_back(VertexId(w));
  }
  if (crease.size() != 2) return false;
  const Vec3 ea = mesh.rest(crease[0]) - pv, eb = mesh.rest(crease[1]) - pv;
  if (!(ea.dot(eb) < 0) || ea.cross(eb).norm() > 1e-10 * ea.norm() * eb.norm()) return false;
  fr.kind = Freedom::Line;
  fr.a = crease[0];
  fr.b = crease[1];
  fr.n = eb.normalized();
  return true;
}

// The faces around v that constrain it: boundary faces (one tag) or, inside the mesh, the
// faces between exactly two labels. Returns false when v is where constraints meet.
bool constraint_faces(const TetMesh& mesh, VertexId v, const ImproveScope& scope, const SmoothOptions& opt,
                      Freedom& fr, bool& cut, bool& mixed) {
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
  std::vector<std::uint16_t> tags;
  for (TetId t : tets) {
    const int lv = mesh.local_index(t, v);
    for (int f = 0; f < 4; ++f) {
      if (f == lv) continue;
      const TetId u = mesh.neighbor(t, f);
      auto fv = mesh.face_vertices(t, f);
      while (fv[0] != v) std::rotate(fv.begin(), fv.begin() + 1, fv.end());
      if (!u.is_valid()) {
        tags.push_back(mesh.face_tag(t, f));
        boundary.push_back(fv);
      } else if (mesh.label(t) == la && mesh.label(u) != la) {
        interface.push_back(fv);  // oriented out of label la
      }
    }
  }
  if (!boundary.empty() && !interface.empty()) return false;  // boundary meets interface
  cut = std::count(tags.begin(), tags.end(), kTagCut) > 0;
  mixed = !tags.empty() && std::count(tags.begin(), tags.end(), tags.front()) != static_cast<long>(tags.size());
  if (cut && !opt.move_cut) return false;
  if (std::count(tags.begin(), tags.end(), kTagCut) != static_cast<long>(tags.size()) && !opt.move_surface) return false;
  if (!interface.empty() && !opt.move_interface) return false;
  fr.fan = boundary.empty() ? std::move(interface) : std::move(boundary);
  fr.tags = std::move(tags);
  return true;
}

Freedom freedom(const TetMesh& mesh, VertexId v, const ImproveScope& scope, const SmoothOptions& opt) {
  Freedom fr;
  if (opt.frozen && opt.frozen->count(v.idx())) return fr;
  if (mesh.incident_tets(v).empty()) return fr;
  bool cut = false, mixed = false;
  if (!constraint_faces(mesh, v, scope, opt, fr, cut, mixed)) return fr;
  if (fr.fan.empty()) {
    fr.kind = Freedom::Free;
    return fr;
  }
  // Where tags meet or the surface bends (boundary only): perhaps a straight crease.
  auto crease_or_fixed = [&]() {
    if (!fr.tags.empty()) crease_line(mesh, v, fr);
    return fr;
  };
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
  // Sliding along a bent feature line moves the surface: it counts as a curved slide (and
  // happens at most once a vertex a pass, see feature_line).
  const bool slid_enough = opt.curved_slides && slides_of(*opt.curved_slides, v) >= opt.max_curved_slides;
  const bool may_bend = opt.slide_curved && opt.feature_line_angle_deg > 0 && !cut && !fr.tags.empty() && !slid_enough;
  if (mixed) {
    if (crease_or_fixed().kind == Freedom::Line || !may_bend) return fr;
    feature_line(mesh, v, normals, from, opt, fr);
    return fr;
  }
  // The front of a cut that ended inside the body, where it bends within the cut's plane (the
  // disc folds onto itself along the front, every face in one plane): v slides along the old
  // front, onto one of its two segments. Both sides move with it and no volume changes; the
  // opening changes by the triangle cut off (or added) at the bend, within the old faces. A
  // straight front is a crease (above: its opening keeps its area). Stuck before, such bends
  // held the worst tets after many partial cuts (docs/improve.md, smoothing).
  if (cut && !mixed && folded_flat(normals)) {
    if (crease_or_fixed().kind != Freedom::Line && !slid_enough) front_line(mesh, v, normals, opt, fr);
    return fr;
  }
  if (!(n.norm() > 0)) return fr;
  n.normalize();
  fr.n = n;
  // Flat: every fan vertex within a tiny fraction of the fan's size from v's plane.
  bool flat = true;
  for (const auto& f : fr.fan) flat = flat && std::abs(n.dot(mesh.rest(f[1]) - pv)) <= 1e-10 * h;
  // Every face must project onto the tangent plane with its orientation (a height field).
  bool height_field = true;
  for (const Vec3& fn : normals) height_field = height_field && n.dot(fn) > 0.2 * fn.norm();
  if (flat && height_field) {
    fr.kind = Freedom::Plane;
    return fr;
  }
  if (crease_or_fixed().kind == Freedom::Line) return fr;
  if (!height_field) {
    if (may_bend) feature_line(mesh, v, normals, from, opt, fr);
    return fr;
  }
  if (!opt.slide_curved || cut || slid_enough) return fr;
  // Smooth: adjacent faces (sharing edge v-y) bend by at most the feature angle.
  const double cos_feature = std::cos(opt.feature_angle_deg * 3.14159265358979323846 / 180);
  for (std::size_t i = 0; i < fr.fan.size(); ++i) {
    const std::size_t j = from.at(fr.fan[i][2].idx());
    if (normals[i].normalized().dot(normals[j].normalized()) < cos_feature) {
      if (may_bend) feature_line(mesh, v, normals, from, opt, fr);
      return fr;
    }
  }
  fr.kind = Freedom::Surface;
  return fr;
}

// Barycentric parents of p (a point of v's star, or of its flat fan) for move_vertex.
bool locate(const TetMesh& mesh, VertexId v, const Vec3& p, const Freedom& fr, std::vector<VertexId>& parents,
            std::vector<double>& weights) {
  double best = -1e300;
  const Vec3& pv = mesh.rest(v);
  if (fr.kind == Freedom::Line) {
    // On the segment from v towards a or b, strictly before it.
    const double t = fr.n.dot(p - pv);
    const VertexId w = t >= 0 ? fr.b : fr.a;
    const double s = std::abs(t) / (mesh.rest(w) - pv).norm();
    if (!(s < 1 - 1e-9)) return false;
    parents = {v, w};
    weights = {1 - s, s};
    return true;
  }
  if (fr.kind == Freedom::Bent || fr.kind == Freedom::Front) {
    // On the segment from v towards a or b (the side n points to), strictly before it.
    const bool to_b = fr.n.dot(p - pv) >= 0;
    if (!(to_b ? fr.b_open : fr.a_open)) return false;
    const VertexId w = to_b ? fr.b : fr.a;
    const Vec3 e = mesh.rest(w) - pv;
    const double s = (p - pv).dot(e) / e.squaredNorm();
    if (!(s >= 0 && s < 1 - 1e-9)) return false;
    parents = {v, w};
    weights = {1 - s, s};
    return true;
  }
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
    best = star_coordinates(mesh, v, p, parents, weights);
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

// Moving v to p changes each label's volume by the change of v's tets of that label. Spends
// the change from the allowance, or refuses (false) when a label would pass its limit.
bool spend_volume(const TetMesh& mesh, VertexId v, const Vec3& p, VolumeAllowance& allowance) {
  std::unordered_map<int, double> delta;
  for (TetId t : mesh.incident_tets(v)) {
    std::array<Vec3, 4> x;
    const auto& tv = mesh.tet_vertices(t);
    for (int k = 0; k < 4; ++k) x[k] = tv[k] == v ? p : mesh.rest(tv[k]);
    const double after = (x[1] - x[0]).cross(x[2] - x[0]).dot(x[3] - x[0]) / 6;
    delta[mesh.label(t)] += after - mesh.volume(t);
  }
  for (const auto& [label, d] : delta)
    if (!allowance.allows(label, d)) return false;
  for (const auto& [label, d] : delta) allowance.moved[label] += d;
  return true;
}

}  // namespace

SmoothMove smooth_vertex_how(TetMesh& mesh, VertexId v, const ImproveScope& scope, const SmoothOptions& opt) {
  const Freedom fr = freedom(mesh, v, scope, opt);
  if (fr.kind == Freedom::Fixed) return SmoothMove::None;
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
  AngleQuality orig, at_best;  // star.at(p0, tg) and star.at(best_p, tg), from the ascent
  AscentOptions ao;
  ao.iterations = opt.iterations;
  ao.scale = hmin;
  if (fr.kind != Freedom::Free) {
    (fr.kind == Freedom::Line || fr.kind == Freedom::Bent || fr.kind == Freedom::Front ? ao.line : ao.normal) = &fr.n;
    ao.project = [&](Vec3& p) { return place(mesh, v, p, fr, p); };
  }
  const Vec3 best_p = ascend(star, p0, tg, ao, &orig, &at_best);
  if (best_p == p0) return SmoothMove::None;
  std::vector<VertexId> parents;
  std::vector<double> weights;
  if (!locate(mesh, v, best_p, fr, parents, weights)) return SmoothMove::None;
  const Vec3 actual = combine(mesh, parents, weights);
  // The located point is usually the ascent's own (bit for bit): its figures are known then.
  const AngleQuality at_actual = std::memcmp(&actual, &best_p, sizeof actual) == 0 ? at_best : star.at(actual, tg);
  if (!better(at_actual, orig, tg) || !mesh.is_move_ok(v, actual)) return SmoothMove::None;
  const bool moves_surface = fr.kind == Freedom::Surface || fr.kind == Freedom::Bent;
  if (moves_surface && opt.volume && !spend_volume(mesh, v, actual, *opt.volume)) return SmoothMove::None;
  mesh.move_vertex(v, parents, weights);
  // A front slide moves no volume, but leaves the old line like a feature slide: counted the same.
  if ((moves_surface || fr.kind == Freedom::Front) && opt.curved_slides) ++(*opt.curved_slides)[v.idx()];
  switch (fr.kind) {
    case Freedom::Free: return SmoothMove::Free;
    case Freedom::Plane: return SmoothMove::Plane;
    case Freedom::Surface: return SmoothMove::Surface;
    case Freedom::Line: return SmoothMove::Crease;
    case Freedom::Front: return SmoothMove::Front;
    default: return SmoothMove::FeatureLine;
  }
}

}  // namespace incise
