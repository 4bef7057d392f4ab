#include "quality/flips.h"

#include <algorithm>
#include <optional>

#include "mesh/errors.h"
#include "quality/boundary_flips.h"
#include "quality/edge_removal.h"
#include "quality/multi_face_removal.h"

namespace incise {

namespace {

struct Candidate {
  AngleQuality after;
  FlipOutcome::Kind kind = FlipOutcome::None;
  TetId tet;  // 2-3: the tet and face
  int face = -1;
  VertexId a, b;  // edge removal; multi-face removal: the apexes u, w
  std::vector<std::array<int, 3>> triangles;
  std::vector<std::array<VertexId, 3>> faces;  // multi-face removal
  std::vector<TetId> removed;
  std::optional<BoundaryEdgeRemoval> boundary;
};

AngleQuality worst_of(const TetMesh& mesh, std::span<const TetId> tets, const AngleTargets& targets) {
  AngleQuality w;
  for (TetId t : tets) w.combine(angle_quality(mesh, t, targets));
  return w;
}

bool same_label_in_scope(const TetMesh& mesh, std::span<const TetId> tets, const ImproveScope& scope) {
  for (TetId t : tets)
    if (!scope.contains(t) || mesh.label(t) != mesh.label(tets.front())) return false;
  return true;
}

void consider_flip23(const TetMesh& mesh, TetId t, int f, const ImproveScope& scope, std::vector<Candidate>& out) {
  const TetId u = mesh.neighbor(t, f);
  if (!u.is_valid()) return;
  const TetId pair[2] = {t, u};
  if (!same_label_in_scope(mesh, pair, scope)) return;
  const VertexId a = mesh.tet_vertices(t)[f];
  VertexId b;
  for (int k = 0; k < 4; ++k)
    if (mesh.neighbor(u, k) == t) b = mesh.tet_vertices(u)[k];
  const auto x = mesh.face_vertices(t, f);
  // better() needs a worst q above the old one's: the new tets stop at the first that is not.
  const AngleQuality before = worst_of(mesh, pair, scope.targets);
  AngleQuality after;
  for (int k = 0; k < 3; ++k) {
    after.combine(angle_quality(mesh.rest(x[k]), mesh.rest(x[(k + 1) % 3]), mesh.rest(a), mesh.rest(b), scope.targets));
    if (!(after.q > before.q + 1e-6)) return;
  }
  if (!better(after, before, scope.targets)) return;
  Candidate c;
  c.after = after;
  c.kind = FlipOutcome::Flip23;
  c.tet = t;
  c.face = f;
  c.removed = {t, u};
  out.push_back(std::move(c));
}

void consider_edge_removal(const TetMesh& mesh, VertexId a, VertexId b, const ImproveScope& scope, int max_ring,
                           const SurfaceReshape* reshape, std::vector<Candidate>& out) {
  TetMesh::EdgeStar star;
  try {
    star = mesh.edge_star(a, b);
  } catch (const InvalidMesh&) {
    return;  // several fans: not an edge a flip can remove
  }
  const int n = static_cast<int>(star.tets.size());
  if (!star.closed) {
    if (auto plan = plan_boundary_edge_removal(mesh, a, b, scope, max_ring, reshape)) {
      Candidate c;
      c.after = plan->after;
      c.kind = FlipOutcome::BoundaryFlip;
      c.removed = plan->removed;
      c.boundary = std::move(plan);
      out.push_back(std::move(c));
    }
    return;
  }
  if (n < 3 || n > max_ring || !same_label_in_scope(mesh, star.tets, scope)) return;
  std::vector<Vec3> ring;
  ring.reserve(n);
  for (VertexId c : star.ring) ring.push_back(mesh.rest(c));
  // better() needs a worst q above the old one's by 1e-6: the search skips what cannot.
  const AngleQuality before = worst_of(mesh, star.tets, scope.targets);
  RingTriangulation best = best_ring_triangulation(ring, mesh.rest(a), mesh.rest(b), scope.targets, before.q + 1e-6);
  if (!better(best.worst, before, scope.targets)) return;
  Candidate c;
  c.after = best.worst;
  c.kind = n == 3 ? FlipOutcome::Flip32 : n == 4 ? FlipOutcome::Flip44 : FlipOutcome::EdgeRemoval;
  c.a = a;
  c.b = b;
  c.triangles = std::move(best.triangles);
  c.removed = star.tets;
  out.push_back(std::move(c));
}

// A disc of one face is the 2-3 flip (consider_flip23). One of two faces is a 4-4 flip of their
// common edge (an edge of t) onto the diagonal u-w, counted as such; consider_edge_removal
// offers only that edge's best diagonal, which the mesh may refuse (the other diagonal is an
// edge elsewhere), so this one is kept as a candidate too.
void consider_multi_face(const TetMesh& mesh, TetId t, int f, const ImproveScope& scope, int max_sandwich,
                         std::vector<Candidate>& out) {
  auto plan = best_multi_face_removal(mesh, t, f, scope, max_sandwich);
  if (!plan || plan->faces.size() < 2) return;
  if (!better(plan->after, worst_of(mesh, plan->removed, scope.targets), scope.targets)) return;
  Candidate c;
  c.after = plan->after;
  c.kind = plan->faces.size() == 2 ? FlipOutcome::Flip44 : FlipOutcome::MultiFaceRemoval;
  c.a = plan->u;
  c.b = plan->w;
  c.faces = std::move(plan->faces);
  c.removed = std::move(plan->removed);
  out.push_back(std::move(c));
}

// Net tets a candidate adds.
long growth_of(const Candidate& c) {
  const long removed = static_cast<long>(c.removed.size());
  switch (c.kind) {
    case FlipOutcome::Flip23: return 1;
    case FlipOutcome::BoundaryFlip: return static_cast<long>(c.boundary->triangles.size() * 2) - removed;
    default:
      if (!c.faces.empty()) return static_cast<long>(c.faces.size() + 2) - removed;  // multi-face removal
      return static_cast<long>(c.triangles.size() * 2) - removed;
  }
}

}  // namespace

FlipOutcome improve_by_flip(TetMesh& mesh, TetId t, const ImproveScope& scope, const FlipOptions& opt) {
  std::vector<Candidate> cands;
  const auto v = mesh.tet_vertices(t);
  for (int f = 0; f < 4; ++f) {
    consider_flip23(mesh, t, f, scope, cands);
    if (opt.multi_face) consider_multi_face(mesh, t, f, scope, opt.max_sandwich, cands);
  }
  for (int i = 0; i < 4; ++i)
    for (int j = i + 1; j < 4; ++j) consider_edge_removal(mesh, v[i], v[j], scope, opt.max_ring, opt.reshape, cands);
  // Best result first; the mesh's own check may still refuse one (an edge the flip would
  // create exists elsewhere, or a new tet is too flat to trust its orientation).
  std::sort(cands.begin(), cands.end(), [](const Candidate& x, const Candidate& y) { return x.after.q > y.after.q; });
  FlipOutcome out;
  for (auto& c : cands) {
    if (growth_of(c) > scope.growth_left) continue;
    if (c.kind == FlipOutcome::BoundaryFlip) {
      out.added = remove_boundary_edge(mesh, *c.boundary);
      out.surface_moved = c.boundary->volume_change != 0;
      if (out.surface_moved && opt.reshape_volume)
        opt.reshape_volume->moved[c.boundary->label] += c.boundary->volume_change;
    } else if (!c.faces.empty()) {  // multi-face removal (a 4-4 flip when it has two faces)
      if (!mesh.is_multi_face_removal_ok(c.a, c.b, c.faces)) continue;
      out.added = mesh.remove_faces(c.a, c.b, c.faces);
    } else if (c.kind == FlipOutcome::Flip23) {
      if (!mesh.is_flip23_ok(c.tet, c.face)) continue;
      auto added = mesh.flip23(c.tet, c.face);
      out.added.assign(added.begin(), added.end());
    } else {
      if (!mesh.is_edge_removal_ok(c.a, c.b, c.triangles)) continue;
      out.added = mesh.remove_edge(c.a, c.b, c.triangles);
    }
    out.kind = c.kind;
    out.removed = std::move(c.removed);
    return out;
  }
  return out;
}

}  // namespace incise
