#include "quality/insertion.h"

#include <algorithm>
#include <unordered_set>

#include "mesh/errors.h"
#include "quality/star_ascent.h"

namespace incise {

namespace {

struct Cavity {
  std::vector<TetId> tets;
  IdSet in;
  bool add(TetId t) {
    if (!in.insert(t.idx()).second) return false;
    tets.push_back(t);
    return true;
  }
};

// A boundary face of the cavity (oriented towards the inside) and the tet across it (invalid
// on the mesh boundary).
struct Side {
  std::array<VertexId, 3> face;
  TetId across;
};

// Boundary insertion: the boundary face (3 vertices) or edge (2) the new vertex goes into; empty
// for an interior insertion.
struct OnBoundary {
  std::vector<VertexId> parents;
  bool holds(const std::array<VertexId, 3>& f) const {
    if (parents.empty()) return false;
    for (VertexId p : parents)
      if (std::find(f.begin(), f.end(), p) == f.end()) return false;
    return true;
  }
};

// The cavity's boundary faces but those a boundary insertion splits (mesh boundary faces
// holding the boundary face or edge).
std::vector<Side> sides(const TetMesh& mesh, const Cavity& c, const OnBoundary& skip) {
  std::vector<Side> out;
  for (TetId t : c.tets)
    for (int f = 0; f < 4; ++f) {
      const TetId n = mesh.neighbor(t, f);
      if (n.is_valid() && c.in.count(n.idx())) continue;
      if (!n.is_valid() && skip.holds(mesh.face_vertices(t, f))) continue;
      const auto x = mesh.face_vertices(t, f);
      out.push_back({{x[0], x[2], x[1]}, n});
    }
  return out;
}

OpenStar cones(const TetMesh& mesh, const std::vector<Side>& s) {
  OpenStar star;
  for (const Side& x : s) {
    star.tets.push_back({mesh.rest(x.face[0]), mesh.rest(x.face[1]), mesh.rest(x.face[2]), Vec3::Zero()});
    star.slot.push_back(3);
  }
  return star;
}

bool clearly_positive(const std::array<Vec3, 4>& x) {
  const Vec3 e1 = x[1] - x[0], e2 = x[2] - x[0], e3 = x[3] - x[0];
  const double l = std::max({e1.norm(), e2.norm(), e3.norm(), (x[2] - x[1]).norm(), (x[3] - x[1]).norm(),
                             (x[3] - x[2]).norm()});
  return e1.dot(e2.cross(e3)) > 1e-12 * l * l * l;
}

bool joinable(const TetMesh& mesh, TetId n, int label, const ImproveScope& scope) {
  return n.is_valid() && mesh.label(n) == label && scope.contains(n);
}

// Grows c at point p, across a face p does not see or else across the face whose new tet is
// worst, up to max_cavity tets, and keeps the cavity along the way whose worst new tet is best
// (a new tet's quality can need two steps to rise). False when no cavity on the way is seen
// from p.
bool grow(const TetMesh& mesh, Cavity& c, const Vec3& p, const ImproveScope& scope, int max_cavity,
          const OnBoundary& on) {
  const int label = mesh.label(c.tets.front());
  Cavity best;
  double best_q = -1e300;
  for (;;) {
    const auto s = sides(mesh, c, on);
    const OpenStar star = cones(mesh, s);
    std::size_t worst = 0;
    double wq = 1e300;
    int blind = -1;
    for (std::size_t i = 0; i < s.size(); ++i) {
      auto x = star.tets[i];
      x[3] = p;
      if (blind < 0 && !clearly_positive(x)) blind = static_cast<int>(i);
      const double q = star.one(i, p, scope.targets).q;
      if (q < wq) wq = q, worst = i;
    }
    if (blind < 0 && wq > best_q) best = c, best_q = wq;
    const TetId n = s[blind >= 0 ? static_cast<std::size_t>(blind) : worst].across;
    if (static_cast<int>(c.tets.size()) >= max_cavity || !joinable(mesh, n, label, scope)) break;
    c.add(n);
  }
  if (best.tets.empty()) return false;
  c = std::move(best);
  return true;
}

// Bowyer-Watson: the tets reachable from t through faces (one label, in scope) whose
// circumsphere holds p.
void delaunay_cavity(const TetMesh& mesh, Cavity& c, const Vec3& p, const ImproveScope& scope, int max_cavity) {
  const int label = mesh.label(c.tets.front());
  for (std::size_t i = 0; i < c.tets.size() && static_cast<int>(c.tets.size()) < max_cavity; ++i)
    for (int f = 0; f < 4 && static_cast<int>(c.tets.size()) < max_cavity; ++f) {
      const TetId n = mesh.neighbor(c.tets[i], f);
      if (!joinable(mesh, n, label, scope) || c.in.count(n.idx())) continue;
      const auto& v = mesh.tet_vertices(n);
      Eigen::Matrix3d a;
      Eigen::Vector3d b;
      for (int k = 0; k < 3; ++k) {
        const Vec3 d = mesh.rest(v[k + 1]) - mesh.rest(v[0]);
        a.row(k) = 2 * d.transpose();
        b[k] = d.squaredNorm();
      }
      const Vec3 cc = a.partialPivLu().solve(b);  // circumcenter relative to v[0]
      if ((p - mesh.rest(v[0]) - cc).squaredNorm() < cc.squaredNorm()) c.add(n);
    }
}

struct Plan {
  Cavity cavity;
  OnBoundary on;
  std::array<VertexId, 4> parents;  // interior: a cavity tet holding the point
  std::array<double, 4> weights;
  std::vector<double> boundary_weights;  // boundary: the point in on.parents
  AngleQuality after;
};

// Barycentric coordinates of p's projection in triangle (a, b, c).
std::array<double, 3> in_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 n = (b - a).cross(c - a);
  const double nn = n.squaredNorm();
  return {(b - p).cross(c - p).dot(n) / nn, (c - p).cross(a - p).dot(n) / nn, (a - p).cross(b - p).dot(n) / nn};
}

std::optional<Plan> plan_at(const TetMesh& mesh, TetId t, const Vec3& start, bool delaunay, const OnBoundary& on,
                            const std::vector<TetId>& seed, const ImproveScope& scope, int max_cavity, int iterations,
                            bool* growth_refused) {
  Plan plan;
  plan.on = on;
  plan.cavity.add(t);
  for (TetId s : seed) plan.cavity.add(s);
  Vec3 p0 = start;
  if (!seed.empty()) {
    // A seeded cavity is larger than the ascent's reach from one point: start it from the best
    // of a few, the given point and those a quarter and half of the way to each of the
    // cavity's vertices, by the worst new tet.
    const OpenStar star = cones(mesh, sides(mesh, plan.cavity, on));
    std::vector<Vec3> corners;
    for (TetId c : plan.cavity.tets)
      for (VertexId v : mesh.tet_vertices(c)) corners.push_back(mesh.rest(v));
    double best = star.at(start, scope.targets).q;
    for (const Vec3& w : corners)
      for (double f : {0.25, 0.5}) {
        const Vec3 p = start + f * (w - start);
        const double q = star.at(p, scope.targets).q;
        if (q > best) best = q, p0 = p;
      }
  }
  if (delaunay) delaunay_cavity(mesh, plan.cavity, p0, scope, max_cavity);
  if (!grow(mesh, plan.cavity, p0, scope, max_cavity, on)) return std::nullopt;
  // Place the point by the ascent on its new tets (within the face for a boundary insertion),
  // then let the cavity follow it once.
  double h = 1e300;
  for (TetId c : plan.cavity.tets)
    for (VertexId v : mesh.tet_vertices(c)) h = std::min(h, (mesh.rest(v) - p0).norm());
  AscentOptions ao;
  ao.iterations = iterations;
  ao.scale = h;
  std::vector<Vec3> bx;
  for (VertexId v : on.parents) bx.push_back(mesh.rest(v));
  const auto coords = [&](const Vec3& q) {
    if (bx.size() == 3) {
      const auto w = in_triangle(q, bx[0], bx[1], bx[2]);
      return std::vector<double>(w.begin(), w.end());
    }
    const double s = (q - bx[0]).dot(bx[1] - bx[0]) / (bx[1] - bx[0]).squaredNorm();
    return std::vector<double>{1 - s, s};
  };
  Vec3 dir;
  if (bx.size() == 3) {
    dir = (bx[1] - bx[0]).cross(bx[2] - bx[0]).normalized();
    ao.normal = &dir;
  } else if (bx.size() == 2) {
    dir = (bx[1] - bx[0]).normalized();
    ao.line = &dir;
  }
  if (!bx.empty())
    ao.project = [&](Vec3& q) {
      const auto w = coords(q);
      return *std::min_element(w.begin(), w.end()) > 0.05;
    };
  const Vec3 p = ascend(cones(mesh, sides(mesh, plan.cavity, on)), p0, scope.targets, ao);
  if (!grow(mesh, plan.cavity, p, scope, max_cavity, on)) return std::nullopt;
  const auto s = sides(mesh, plan.cavity, on);
  const long growth = static_cast<long>(s.size()) - static_cast<long>(plan.cavity.tets.size());
  if (growth > scope.growth_left) {
    if (growth_refused) *growth_refused = true;
    return std::nullopt;
  }
  Vec3 actual = Vec3::Zero();
  if (!bx.empty()) {
    plan.boundary_weights = coords(p);
    for (std::size_t k = 0; k < bx.size(); ++k) actual += plan.boundary_weights[k] * bx[k];
    if (!mesh.is_boundary_cavity_insertion_ok(plan.cavity.tets, on.parents, plan.boundary_weights))
      return std::nullopt;
  } else {
    // Parents: the cavity tet that holds p best; the position is what the record computes.
    double best = -1e300;
    for (TetId c : plan.cavity.tets) {
      const auto& tv = mesh.tet_vertices(c);
      Eigen::Matrix3d m;
      for (int k = 0; k < 3; ++k) m.col(k) = mesh.rest(tv[k + 1]) - mesh.rest(tv[0]);
      const Vec3 l = m.partialPivLu().solve(p - mesh.rest(tv[0]));
      const std::array<double, 4> w = {1 - l.sum(), l[0], l[1], l[2]};
      const double lo = *std::min_element(w.begin(), w.end());
      if (lo > best) best = lo, plan.parents = tv, plan.weights = w;
    }
    if (!(best > -1e-9)) return std::nullopt;
    double sum = 0;
    for (double& w : plan.weights) sum += (w = std::max(w, 0.0));
    for (int k = 0; k < 4; ++k) actual += (plan.weights[k] /= sum) * mesh.rest(plan.parents[k]);
    if (!mesh.is_cavity_insertion_ok(plan.cavity.tets, actual)) return std::nullopt;
  }
  plan.after = cones(mesh, s).at(actual, scope.targets);
  AngleQuality before;
  for (TetId c : plan.cavity.tets) before.combine(angle_quality(mesh, c, scope.targets));
  if (!better(plan.after, before, scope.targets)) return std::nullopt;
  return plan;
}

Vec3 circumcenter(const std::array<Vec3, 4>& x) {
  Eigen::Matrix3d a;
  Eigen::Vector3d b;
  for (int k = 0; k < 3; ++k) {
    const Vec3 d = x[k + 1] - x[0];
    a.row(k) = 2 * d.transpose();
    b[k] = d.squaredNorm();
  }
  return x[0] + a.partialPivLu().solve(b);
}

}  // namespace

std::optional<InsertionOutcome> improve_by_insertion(TetMesh& mesh, TetId t, const ImproveScope& scope,
                                                     const InsertionOptions& opt) {
  const auto v = mesh.tet_vertices(t);
  std::array<Vec3, 4> x;
  for (int k = 0; k < 4; ++k) x[k] = mesh.rest(v[k]);
  const Vec3 bary = 0.25 * (x[0] + x[1] + x[2] + x[3]);
  // Start points: (point, Bowyer-Watson cavity first, boundary face).
  struct Start {
    Vec3 p;
    bool delaunay;
    OnBoundary on;
    std::vector<TetId> seed = {};  // more tets the cavity starts with
  };
  std::vector<Start> starts = {{bary, false, {}}, {bary, true, {}}};
  const Vec3 cc = circumcenter(x);
  if (cc.allFinite()) starts.push_back({cc, true, {}});
  for (int f = 0; f < 4; ++f) {
    const Vec3 centroid = (bary * 4 - x[f]) / 3;
    if (mesh.neighbor(t, f).is_valid())
      starts.push_back({centroid, false, {}});
    else if (opt.boundary_tags && opt.boundary_tags(mesh.face_tag(t, f)))
      starts.push_back({centroid, false, {{v[kFaceLocal[f][0]], v[kFaceLocal[f][1]], v[kFaceLocal[f][2]]}}});
  }
  // The star of each edge of t: a vertex inside it splits the angles around the edge (at a
  // boundary edge its two boundary faces keep the edge, which two new tets share; inside, the
  // edge goes). Growing from t alone stops there, at the first boundary face the point on the
  // edge does not see. The point starts between the edge's midpoint and the star's ring. And
  // the union of the six stars (every tet sharing an edge with t, so that t's angles at all its
  // edges are shared anew), from t's barycenter.
  const int label = mesh.label(t);
  // The tets around edge (v[i], v[j]): one fan (an edge the tets reach only around a cut's
  // front, not through faces, is left alone), one label, in scope.
  const auto edge_star = [&](int i, int j, std::vector<TetId>& star, Vec3& ring) {
    TetMesh::EdgeStar es;
    try {
      es = mesh.edge_star(v[i], v[j]);
    } catch (const InvalidMesh&) {
      return false;
    }
    ring = Vec3::Zero();
    for (VertexId w : es.ring) ring += mesh.rest(w);
    ring /= double(es.ring.size());
    for (TetId u : es.tets) {
      if (mesh.label(u) != label || !scope.contains(u)) return false;
      if (u != t) star.push_back(u);
    }
    return static_cast<int>(star.size()) + 1 <= opt.max_cavity;
  };
  std::vector<TetId> edge_stars;
  bool all_ok = opt.edge_stars;
  for (int i = 0; i < 4 && opt.edge_stars; ++i)
    for (int j = i + 1; j < 4; ++j) {
      std::vector<TetId> star;
      Vec3 ring;
      if (!edge_star(i, j, star, ring)) {
        all_ok = false;
        continue;
      }
      for (TetId u : star)
        if (std::find(edge_stars.begin(), edge_stars.end(), u) == edge_stars.end()) edge_stars.push_back(u);
      all_ok = all_ok && static_cast<int>(edge_stars.size()) + 1 <= opt.max_cavity;
      if (!star.empty()) starts.push_back({0.5 * (0.5 * (x[i] + x[j]) + ring), false, {}, std::move(star)});
    }
  if (all_ok && !edge_stars.empty()) starts.push_back({bary, false, {}, std::move(edge_stars)});
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) {
      const Vec3 mid = 0.5 * (x[i] + x[j]);
      starts.push_back({mid, false, {}});
      // On a boundary edge of t: its boundary faces (the check finds them) take the vertex.
      bool boundary_edge = false;
      for (int f = 0; f < 4; ++f)
        boundary_edge = boundary_edge || (f != i && f != j && !mesh.neighbor(t, f).is_valid() &&
                                          opt.boundary_tags && opt.boundary_tags(mesh.face_tag(t, f)));
      if (boundary_edge) starts.push_back({mid, false, {{v[i], v[j]}}});
    }
  std::optional<Plan> best;
  for (const Start& s : starts)
    if (auto plan = plan_at(mesh, t, s.p, s.delaunay, s.on, s.seed, scope, opt.max_cavity, opt.iterations,
                            opt.growth_refused))
      if (!best || plan->after.q > best->after.q) best = std::move(plan);
  if (!best) return std::nullopt;
  InsertionOutcome out;
  out.removed = best->cavity.tets;
  out.on_boundary = !best->on.parents.empty();
  out.vertex = out.on_boundary
                   ? mesh.insert_in_cavity_on_boundary(best->cavity.tets, best->on.parents, best->boundary_weights)
                   : mesh.insert_in_cavity(best->cavity.tets, best->parents, best->weights);
  const auto inc = mesh.incident_tets(out.vertex);
  out.added.assign(inc.begin(), inc.end());
  return out;
}

}  // namespace incise
