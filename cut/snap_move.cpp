#include "cut/snap_move.h"

#include <algorithm>
#include <array>

#include "quality/metrics.h"

namespace incise::cut_detail {

namespace {
double signed_volume(const std::array<Vec3, 4>& x) { return (x[1] - x[0]).dot((x[2] - x[0]).cross(x[3] - x[0])); }

// Inside the mesh and inside one label: no face of its star is boundary or an interface.
bool interior_one_label(const TetMesh& mesh, VertexId v) {
  const auto tets = mesh.incident_tets(v);
  if (tets.empty()) return false;
  const int label = mesh.label(tets.front());
  for (TetId t : tets) {
    if (mesh.label(t) != label) return false;
    const int lv = mesh.local_index(t, v);
    for (int f = 0; f < 4; ++f) {
      if (f == lv) continue;
      const TetId u = mesh.neighbor(t, f);
      if (!u.is_valid() || mesh.label(u) != label) return false;
    }
  }
  return true;
}

double star_min_dihedral(const TetMesh& mesh, VertexId v, const Vec3& at) {
  double worst = 180;
  for (TetId t : mesh.incident_tets(v)) {
    std::array<Vec3, 4> x;
    const auto& tv = mesh.tet_vertices(t);
    for (int k = 0; k < 4; ++k) x[k] = tv[k] == v ? at : mesh.rest(tv[k]);
    worst = std::min(worst, tet_quality(x[0], x[1], x[2], x[3]).min_dihedral);
  }
  return worst;
}
}  // namespace

std::optional<Vec3> move_onto_plane(TetMesh& mesh, VertexId v, const Piece& piece,
                                    const std::function<Vec3(VertexId)>& position,
                                    const IdSet& fixed) {
  if (fixed.count(v.idx()) || !interior_one_label(mesh, v)) return std::nullopt;
  const Vec3 x = position(v);
  const Vec3 target = x - piece.distance(x) * piece.normal;
  // The target's barycentric weights in the star tet that holds it best (current shape);
  // every star tet must keep its orientation there, in the current shape and at rest.
  double best = -1e300;
  std::array<VertexId, 4> parents;
  std::array<double, 4> weights{};
  for (TetId t : mesh.incident_tets(v)) {
    const auto& tv = mesh.tet_vertices(t);
    std::array<Vec3, 4> c;
    for (int k = 0; k < 4; ++k) c[k] = position(tv[k]);
    const double vol = signed_volume(c);
    std::array<Vec3, 4> moved = c;
    moved[mesh.local_index(t, v)] = target;
    if (!(vol > 0) || !(signed_volume(moved) > 0)) return std::nullopt;
    std::array<double, 4> w;
    for (int k = 0; k < 4; ++k) {
      std::array<Vec3, 4> s = c;
      s[k] = target;
      w[k] = signed_volume(s) / vol;
    }
    const double m = *std::min_element(w.begin(), w.end());
    if (m > best) {
      best = m;
      parents = tv;
      weights = w;
    }
  }
  if (!(best > -1e-9)) return std::nullopt;
  double sum = 0;
  for (double& w : weights) sum += (w = std::max(w, 0.0));
  Vec3 rest = Vec3::Zero();
  for (int k = 0; k < 4; ++k) rest += (weights[k] /= sum) * mesh.rest(parents[k]);
  if (!mesh.is_move_ok(v, rest)) return std::nullopt;
  const double before = star_min_dihedral(mesh, v, mesh.rest(v));
  if (star_min_dihedral(mesh, v, rest) < std::min(before, kSnapMoveFloorDeg)) return std::nullopt;
  mesh.move_vertex(v, parents, weights);
  Vec3 now = Vec3::Zero();
  for (int k = 0; k < 4; ++k) now += weights[k] * (parents[k] == v ? x : position(parents[k]));
  return now;
}

}  // namespace incise::cut_detail
