#include "quality/insertion.h"

#include <algorithm>

#include "mesh/errors.h"
#include "quality/star_ascent.h"

namespace incise {

namespace {

struct Plan {
  VertexId a, b;
  std::vector<TetId> removed;
  std::array<VertexId, 4> parents;
  std::array<double, 4> weights;
  AngleQuality after;
};

bool clearly_positive(const std::array<Vec3, 4>& x) {
  const Vec3 e1 = x[1] - x[0], e2 = x[2] - x[0], e3 = x[3] - x[0];
  const double l = std::max({e1.norm(), e2.norm(), e3.norm(), (x[2] - x[1]).norm(), (x[3] - x[1]).norm(),
                             (x[3] - x[2]).norm()});
  return e1.dot(e2.cross(e3)) > 1e-12 * l * l * l;
}

std::optional<Plan> plan_split(const TetMesh& mesh, VertexId a, VertexId b, const ImproveScope& scope, int max_ring,
                               int iterations) {
  TetMesh::EdgeStar star;
  try {
    star = mesh.edge_star(a, b);
  } catch (const InvalidMesh&) {
    return std::nullopt;
  }
  if (!star.closed || static_cast<int>(star.tets.size()) > max_ring) return std::nullopt;
  AngleQuality before;
  for (TetId t : star.tets) {
    if (!scope.contains(t) || mesh.label(t) != mesh.label(star.tets.front())) return std::nullopt;
    before.combine(angle_quality(mesh, t, scope.targets));
  }
  // The children of each tet around the edge, as split_edge makes them: the tet with a's
  // slot, then b's slot, taken by the new vertex.
  OpenStar children;
  const Vec3 mid = 0.5 * (mesh.rest(a) + mesh.rest(b));
  double h = 1e300;
  for (TetId t : star.tets) {
    std::array<Vec3, 4> x;
    for (int k = 0; k < 4; ++k) {
      x[k] = mesh.rest(mesh.tet_vertices(t)[k]);
      h = std::min(h, (x[k] - mid).norm());
    }
    for (VertexId e : {a, b}) {
      children.tets.push_back(x);
      children.slot.push_back(mesh.local_index(t, e));
    }
  }
  AscentOptions ao;
  ao.iterations = iterations;
  ao.scale = h;
  const Vec3 p = ascend(children, mid, scope.targets, ao);
  // Parents: the old tet around the edge that holds p; the position is what move_vertex
  // will compute from them.
  Plan plan;
  double best = -1e300;
  for (TetId t : star.tets) {
    const auto& tv = mesh.tet_vertices(t);
    Eigen::Matrix3d m;
    for (int k = 0; k < 3; ++k) m.col(k) = mesh.rest(tv[k + 1]) - mesh.rest(tv[0]);
    const Vec3 l = m.partialPivLu().solve(p - mesh.rest(tv[0]));
    const std::array<double, 4> w = {1 - l.sum(), l[0], l[1], l[2]};
    const double lo = *std::min_element(w.begin(), w.end());
    if (lo > best) best = lo, plan.parents = tv, plan.weights = w;
  }
  if (!(best > -1e-9)) return std::nullopt;
  double s = 0;
  for (double& w : plan.weights) s += (w = std::max(w, 0.0));
  Vec3 actual = Vec3::Zero();
  for (int k = 0; k < 4; ++k) actual += (plan.weights[k] /= s) * mesh.rest(plan.parents[k]);
  for (std::size_t i = 0; i < children.tets.size(); ++i) {
    auto x = children.tets[i];
    x[children.slot[i]] = actual;
    if (!clearly_positive(x)) return std::nullopt;
  }
  plan.after = children.at(actual, scope.targets);
  if (!better(plan.after, before, scope.targets)) return std::nullopt;
  plan.a = a;
  plan.b = b;
  plan.removed = star.tets;
  return plan;
}

}  // namespace

std::optional<InsertionOutcome> improve_by_insertion(TetMesh& mesh, TetId t, const ImproveScope& scope, int max_ring,
                                                     int iterations) {
  const auto v = mesh.tet_vertices(t);
  std::optional<Plan> best;
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j)
      if (auto p = plan_split(mesh, v[i], v[j], scope, max_ring, iterations))
        if (!best || p->after.q > best->after.q) best = std::move(p);
  if (!best) return std::nullopt;
  InsertionOutcome out;
  out.removed = best->removed;
  out.vertex = mesh.split_edge(best->a, best->b, 0.5);
  mesh.move_vertex(out.vertex, best->parents, best->weights);
  const auto inc = mesh.incident_tets(out.vertex);
  out.added.assign(inc.begin(), inc.end());
  return out;
}

}  // namespace incise
