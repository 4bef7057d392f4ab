#include "cut/cut_step.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "cut/predicates.h"
#include "cut/snap_move.h"

namespace incise::cut_detail {

namespace {
// Whether x lies beside the segment [a, b] (its projection on the line between a and b) within
// `reach` of it: at a crease, the crease line.
bool beside_segment(const Vec3& x, const Vec3& a, const Vec3& b, double reach) {
  const Vec3 d = b - a;
  const double len = d.norm();
  if (!(len > 0)) return false;
  const Vec3 f = d / len;
  const double along = f.dot(x - a);
  return along >= 0 && along <= len && ((x - a) - f * along).norm() <= reach;
}
// The floor of the snap threshold: points made by earlier splits are floating point, so a
// vertex meant to lie on a blade is only within rounding of it.
constexpr double kSnapFloor = 1e-6;
// A point the blade's boundary puts in a face, closer than this share of the snap threshold
// (times the tet's longest edge) to one of the face's edges, goes onto that edge
// (CutStep::on_nearby_edge).
constexpr double kEdgeSnap = 0.03;
// The share of the snap distance within which a vertex by a crease front is put on the sheet
// (CutStep::side). The whole snap distance put vertices on the sheet whose neighbours then
// joined other drags at their creases (docs/cut.md#curved-paths).
constexpr double kCreaseFrontShare = 0.1;
// Relative tolerance of "inside the piece" for points that are on its plane.
constexpr double kInsideTol = 1e-9;
// At a sheet's finish, a vertex of the body's surface inside the swept polygon is put on the
// sheet when it is within this fraction of the snap distance; farther, it keeps its side. Kept
// on its side, the edges it has across the plane are split a hair from it, and the tets there
// go below 1 degree with no contraction possible (the edge joins two sheets). Snapping the
// whole distance moves the rim, and the opened area with it, past the 1% the tests allow; half
// keeps it and most of the quality (docs/cut.md#the-defaults).
constexpr double kSurfaceSnapFraction = 0.5;

// On an earlier cut's faces and on no other boundary face (the body's surface).
bool on_cut_only(const TetMesh& m, VertexId v) {
  bool cut = false;
  for (TetId t : m.incident_tets(v))
    for (int f = 0; f < 4; ++f) {
      if (m.tet_vertices(t)[f] == v || m.neighbor(t, f).is_valid()) continue;
      if (m.face_tag(t, f) != kTagCut) return false;
      cut = true;
    }
  return cut;
}

std::uint32_t face_key(TetId t, int f) { return 4 * t.idx() + std::uint32_t(f); }

// The local index, in neighbour n, of the face it shares with t; -1 when they share none.
int shared_face(const TetMesh& m, TetId n, TetId t) {
  for (int j = 0; j < 4; ++j)
    if (m.neighbor(n, j) == t) return j;
  return -1;
}

// Whether splitting tet t at rest point p (barycentric w, slots with w > 0 get a child) gives
// children of clearly positive rest volume. Repeated cuts in one place make small tets; a
// split of an already flat one could round to a zero volume, so the cutter snaps instead.
bool children_ok(const TetMesh& m, TetId t, const Vec3& p, const std::array<double, 4>& w) {
  const auto& tv = m.tet_vertices(t);
  std::array<Vec3, 4> x;
  double l2 = 0;
  for (int k = 0; k < 4; ++k) x[k] = m.rest(tv[k]);
  for (int a = 0; a < 4; ++a)
    for (int b = a + 1; b < 4; ++b) l2 = std::max(l2, (x[a] - x[b]).squaredNorm());
  const double margin = 1e-13 * l2 * std::sqrt(l2);
  for (int s = 0; s < 4; ++s) {
    if (!(w[s] > 0)) continue;
    std::array<Vec3, 4> c = x;
    c[s] = p;
    if (!((c[1] - c[0]).dot((c[2] - c[0]).cross(c[3] - c[0])) > margin)) return false;
  }
  return true;
}
}  // namespace

bool CutStep::edge_split_ok(VertexId a, VertexId b, double s) const {
  const Vec3 p = (1 - s) * mesh_.rest(a) + s * mesh_.rest(b);
  for (TetId t : mesh_.incident_tets(a)) {
    const int lb = mesh_.local_index(t, b);
    if (lb < 0) continue;
    std::array<double, 4> w{0, 0, 0, 0};
    w[mesh_.local_index(t, a)] = 1 - s;
    w[lb] = s;
    if (!children_ok(mesh_, t, p, w)) return false;
  }
  return true;
}

bool CutStep::edge_split_ok_cached(VertexId a, VertexId b, double s) {
  const std::uint64_t edits = mesh_.counters().edits;
  if (edits != split_ok_edits_) {
    split_ok_.clear();
    split_ok_edits_ = edits;
  }
  const std::uint64_t key = std::uint64_t(a.idx()) << 32 | b.idx();
  auto it = split_ok_.find(key);
  if (it != split_ok_.end() && it->second.s == s) return it->second.ok;
  const bool ok = edge_split_ok(a, b, s);
  split_ok_[key] = {s, ok};
  return ok;
}

CutStep::CutStep(TetMesh& mesh, const PositionFn& positions, double snap, CutMemory* memory, bool provisional)
    : mesh_(mesh), positions_(positions), snap_(std::max(snap, kSnapFloor)), memory_(memory),
      provisional_(provisional && memory) {}

void CutStep::decide(std::size_t k, VertexId v, int s) {
  side_cache_[k][v.idx()] = s;
  if (memory_) memory_->side[v.idx()] = s;
}

void CutStep::add_candidates(std::span<const TetId> tets) {
  for (TetId t : tets)
    if (mesh_.is_alive(t) && in_cand_.insert(t.idx()).second) cand_.push_back(t);
}

Vec3 CutStep::position(VertexId v) const {
  auto it = created_pos_.find(v.idx());
  if (it != created_pos_.end()) return it->second;
  return positions_ ? positions_(v) : mesh_.rest(v);
}

std::array<Vec3, 4> CutStep::tet_positions(TetId t) const {
  const auto& tv = mesh_.tet_vertices(t);
  return {position(tv[0]), position(tv[1]), position(tv[2]), position(tv[3])};
}

double CutStep::snap_length(VertexId v) {
  auto& cache = memory_ ? memory_->snap_len : snap_len_;
  auto it = cache.find(v.idx());
  if (it != cache.end()) return it->second;
  // Relative to the mean incident edge: after earlier cuts the shortest edge can be tiny, and
  // a threshold relative to it would stop snapping exactly where slivers pile up.
  const double len = snap_ * mean_incident_edge(v);
  cache[v.idx()] = len;
  return len;
}

void CutStep::note_destroyed(TetId t) {
  if (!born_.count(t.idx())) destroyed_.insert(t.idx());
  else born_.erase(t.idx());
}

void CutStep::note_new_vertex(VertexId p) {
  radius_[p.idx()] = pending_radius_;
  for (TetId t : mesh_.incident_tets(p)) {
    born_.insert(t.idx());
    if (in_cand_.insert(t.idx()).second) cand_.push_back(t);
  }
  // Snap lengths of the neighbours changed (a shorter edge); forget them (a progressive sheet
  // keeps the first measurement: see CutMemory).
  if (!memory_)
    for (TetId t : mesh_.incident_tets(p))
    for (VertexId w : mesh_.tet_vertices(t)) snap_len_.erase(w.idx());
}

double CutStep::star_radius(VertexId v) const {
  const Vec3 x = position(v);
  double l2 = 0;
  for (TetId t : mesh_.incident_tets(v))
    for (VertexId w : mesh_.tet_vertices(t)) l2 = std::max(l2, (position(w) - x).squaredNorm());
  return std::sqrt(l2);
}

double CutStep::vertex_radius(VertexId v) {
  auto it = radius_.find(v.idx());
  // Existing vertices: the floor only. The blade's rim and front must stay a chain of mesh
  // edges for the next step to continue from; snapping them onto nearby vertices breaks the
  // chain, so the snap threshold acts on the blade's plane (side()), not on its boundary.
  return it != radius_.end() ? it->second : snap_length(v) * (kSnapFloor / snap_);
}

VertexId CutStep::insert_point(TetId t, std::array<double, 4> w) {
  for (double& x : w) x = std::max(x, 0.0);
  if (const auto v = snap_to_vertex(t, w)) return *v;
  for (double& x : w)
    if (x < kSnapFloor) x = 0;
  const double sum = w[0] + w[1] + w[2] + w[3];
  const auto tv = mesh_.tet_vertices(t);
  auto nearest = [&] { return tv[std::size_t(std::max_element(w.begin(), w.end()) - w.begin())]; };
  if (!(sum > 0)) return nearest();  // every weight snapped
  for (double& x : w) x /= sum;
  int nz = 0;
  for (double x : w) nz += x > 0;
  if (nz == 3) on_nearby_edge(t, w, nz);
  if (nz == 1) return nearest();
  const std::optional<VertexId> p = nz == 2 ? split_on_edge(t, w) : nz == 3 ? split_on_face(t, w) : split_in_tet(t, w);
  if (!p) return nearest();  // a child would be flat: the nearest vertex instead
  note_new_vertex(*p);
  return *p;
}

void CutStep::on_nearby_edge(TetId t, std::array<double, 4>& w, int& nz) const {
  const auto tv = mesh_.tet_vertices(t);
  Vec3 x = Vec3::Zero();
  double longest = 0;
  for (int k = 0; k < 4; ++k) {
    x += w[k] * position(tv[k]);
    for (int j = k + 1; j < 4; ++j) longest = std::max(longest, (position(tv[k]) - position(tv[j])).norm());
  }
  const double reach = kEdgeSnap * snap_ * longest;
  int best = -1;
  double best_d = reach;
  for (int k = 0; k < 4; ++k) {
    if (!(w[k] > 0)) continue;
    int a = -1, b = -1;  // the face's edge opposite corner k
    for (int j = 0; j < 4; ++j)
      if (j != k && w[j] > 0) (a < 0 ? a : b) = j;
    const Vec3 pa = position(tv[a]), e = position(tv[b]) - pa;
    const double len2 = e.squaredNorm();
    if (!(len2 > 0)) continue;
    const double s = std::clamp((x - pa).dot(e) / len2, 0.0, 1.0);
    const double d = (x - (pa + s * e)).norm();
    if (d < best_d) best = k, best_d = d;
  }
  if (best < 0) return;
  const double rest = 1 - w[best];
  w[best] = 0;
  for (double& y : w) y /= rest;
  --nz;
}

std::optional<VertexId> CutStep::snap_to_vertex(TetId t, const std::array<double, 4>& w) {
  // A point within a vertex's snap radius is that vertex. Vertices made this step get a radius
  // of half the snap threshold times the element they were made in: a blade segment passes
  // within that distance of a point snapped onto an edge, and must not then refine the
  // shrinking faces around it; and a segment that runs (up to rounding) in the plane of a
  // face, tangent to the boundary, meets the new faces again and again at points converging
  // on one spot (a cascade of face splits leaving tets with radius ratio 1e-13). Snapping onto
  // a point made this step keeps the blade's boundary a chain of mesh edges: that point lies on
  // the blade's boundary or surface.
  const auto tv = mesh_.tet_vertices(t);
  const double sum = w[0] + w[1] + w[2] + w[3];
  Vec3 x = Vec3::Zero();
  double longest = 0;
  for (int k = 0; k < 4; ++k) {
    x += w[k] / sum * position(tv[k]);
    for (int j = k + 1; j < 4; ++j) longest = std::max(longest, (position(tv[k]) - position(tv[j])).norm());
  }
  // A point in a face of the body's surface (where the blade's boundary leaves the body)
  // stays in it: snapped onto the tet's fourth vertex, the chain of edges would end inside
  // the body, and the sliver of tissue between it and the surface would hold the two sides
  // of a through-cut together.
  int off_surface = -1;
  for (int k = 0; k < 4; ++k)
    if (w[k] == 0 && !mesh_.neighbor(t, k).is_valid()) off_surface = k;
  int best = -1;
  double best_d = 1e300;
  for (int k = 0; k < 4; ++k) {
    if (k == off_surface) continue;
    const double d = (x - position(tv[k])).norm();
    if (d <= vertex_radius(tv[k]) && d < best_d) {
      best = k;
      best_d = d;
    }
  }
  if (best >= 0) return tv[best];
  pending_radius_ = std::max(kSnapFloor, 0.5 * snap_) * longest;
  return std::nullopt;
}

std::optional<VertexId> CutStep::split_on_edge(TetId t, const std::array<double, 4>& w) {
  const auto tv = mesh_.tet_vertices(t);
  int a = -1, b = -1;
  for (int k = 0; k < 4; ++k)
    if (w[k] > 0) (a < 0 ? a : b) = k;
  if (!edge_split_ok(tv[a], tv[b], w[b])) return std::nullopt;
  for (TetId x : mesh_.incident_tets(tv[a]))
    if (mesh_.local_index(x, tv[b]) >= 0) note_destroyed(x);
  const VertexId p = mesh_.split_edge(tv[a], tv[b], w[b]);
  created_pos_[p.idx()] = w[a] * position(tv[a]) + w[b] * position(tv[b]);
  return p;
}

std::optional<VertexId> CutStep::split_on_face(TetId t, const std::array<double, 4>& w) {
  int f = 0;
  while (w[f] > 0) ++f;
  const auto fv = mesh_.face_vertices(t, f);
  std::array<double, 3> w3;
  Vec3 x = Vec3::Zero(), rest = Vec3::Zero();
  for (int k = 0; k < 3; ++k) {
    w3[k] = w[mesh_.local_index(t, fv[k])];
    x += w3[k] * position(fv[k]);
    rest += w3[k] * mesh_.rest(fv[k]);
  }
  const TetId u = mesh_.neighbor(t, f);
  bool ok = children_ok(mesh_, t, rest, w);
  if (ok && u.is_valid()) {
    std::array<double, 4> wu{0, 0, 0, 0};
    for (int q = 0; q < 3; ++q) wu[mesh_.local_index(u, fv[q])] = w3[q];
    ok = children_ok(mesh_, u, rest, wu);
  }
  if (!ok) return std::nullopt;
  note_destroyed(t);
  if (u.is_valid()) note_destroyed(u);
  const VertexId p = mesh_.split_face(t, f, w3);
  created_pos_[p.idx()] = x;
  return p;
}

std::optional<VertexId> CutStep::split_in_tet(TetId t, const std::array<double, 4>& w) {
  const auto tv = mesh_.tet_vertices(t);
  Vec3 x = Vec3::Zero(), rest = Vec3::Zero();
  for (int k = 0; k < 4; ++k) {
    x += w[k] * position(tv[k]);
    rest += w[k] * mesh_.rest(tv[k]);
  }
  if (!children_ok(mesh_, t, rest, w)) return std::nullopt;
  note_destroyed(t);
  const VertexId p = mesh_.split_tet(t, w);
  created_pos_[p.idx()] = x;
  return p;
}

void CutStep::collect(const Piece& piece, std::span<const TetId> seeds,
                      const std::function<std::vector<TetId>()>& fallback, std::span<const TetId> more) {
  current_piece_ = on_piece_.size();
  on_piece_.emplace_back();
  side_cache_.emplace_back();
  undecided_.emplace_back();
  // Tolerance of the overlap test: a little more than the snap reach, relative to the piece.
  const double tol = 1e-9 * (piece.hi - piece.lo).norm();
  std::vector<TetId> queue;
  IdSet seen;
  auto touches = [&](TetId t) {
    const auto x = tet_positions(t);
    for (const CutTriangle& tri : piece.triangles)
      if (tet_may_touch_triangle(x, tri, tol)) return true;
    return false;
  };
  auto try_seed = [&](TetId t) {
    if (!mesh_.is_alive(t) || !seen.insert(t.idx()).second) return;
    if (touches(t)) queue.push_back(t);
  };
  std::size_t walked = 0;
  auto walk = [&] {
    for (; walked < queue.size(); ++walked) {
      const TetId t = queue[walked];
      if (in_cand_.insert(t.idx()).second) cand_.push_back(t);
      for (int f = 0; f < 4; ++f) {
        const TetId n = mesh_.neighbor(t, f);
        if (n.is_valid() && seen.insert(n.idx()).second && touches(n)) queue.push_back(n);
      }
    }
  };
  for (TetId t : seeds) try_seed(t);
  if (queue.empty() && fallback)
    for (TetId t : fallback()) try_seed(t);
  walk();
  for (TetId t : more) try_seed(t);
  walk();
}

void CutStep::embed_boundary(const Piece& piece) {
  // Which boundary segments each vertex lies on (bit i: segment i). A line through a vertex of
  // a face meets the face's plane only there (or lies in it), so a face with a vertex on the
  // segment has nothing to insert; testing it anyway would intersect the segment with planes
  // it lies in up to rounding, and refine without end.
  SegmentMarks marks;
  const std::vector<bool> known = reuse_known_segments(piece, marks);
  embed_corners(piece, known, marks);
  // Then the segments, one at a time: every face a segment crosses gets the crossing point.
  // One at a time is what makes this end. A split for segment i makes only faces through the
  // new point, which segment i skips, so each of its splits uses up one crossing of the mesh
  // as it was. Interleaving two segments broke that: near a shared corner each one's split
  // made fresh faces for the other, whose crossing then lay on a flatter child of the same
  // tet, without end (a cascade of slivers with radius ratio 1e-21 on the liver).
  for (std::size_t si = 0; si < piece.boundary.size(); ++si)
    if (!known[si]) embed_segment(piece, si, marks);
  for (std::size_t i = 0; i < piece.boundary.size(); ++i) {
    if (known[i]) continue;
    EmbeddedSegment e{piece.boundary[i][0], piece.boundary[i][1], {}};
    for (const auto& [v, bits] : marks)
      if (bits & (1u << i)) e.vertices.emplace_back(v);
    embedded_.push_back(std::move(e));
  }
}

void CutStep::mark_on_segments(SegmentMarks& marks, VertexId v, std::uint32_t segments) {
  marks[v.idx()] |= segments;
  if (on_piece_[current_piece_].insert(v.idx()).second) boundary_vertices_.push_back(v);
  if (memory_) memory_->side[v.idx()] = 0;
}

std::vector<bool> CutStep::reuse_known_segments(const Piece& piece, SegmentMarks& marks) {
  // Segments embedded before (by an earlier piece of this step, or the previous step's front)
  // are reused as they are: embedding the same segment twice would snap differently and
  // leave a strip between the two cut surfaces.
  const std::size_t ns = piece.boundary.size();
  std::vector<bool> known(ns, false);
  for (std::size_t i = 0; i < ns; ++i)
    for (const EmbeddedSegment& e : embedded_) {
      const auto& g = piece.boundary[i];
      if ((e.a == g[0] && e.b == g[1]) || (e.a == g[1] && e.b == g[0])) {
        known[i] = true;
        for (VertexId v : e.vertices)
          if (on_segment(v, e.a, e.b)) mark_on_segments(marks, v, 1u << i);
        break;
      }
    }
  return known;
}

void CutStep::embed_corners(const Piece& piece, const std::vector<bool>& known, SegmentMarks& marks) {
  // Each corner inside the body becomes a vertex (or snaps to one). Corner i starts segment i
  // and ends segment i-1 (the boundary is a closed loop).
  const std::size_t ns = piece.boundary.size();
  for (std::size_t i = 0; i < ns; ++i) {
    if (known[i] || known[(i + ns - 1) % ns]) continue;
    const Vec3 c = piece.boundary[i][0];
    const std::uint32_t bits = (1u << i) | (1u << ((i + ns - 1) % ns));
    for (std::size_t j = 0; j < cand_.size(); ++j) {
      const TetId t = cand_[j];
      if (!mesh_.is_alive(t)) continue;
      const auto x = tet_positions(t);
      const double vol = (x[1] - x[0]).dot((x[2] - x[0]).cross(x[3] - x[0]));
      if (!(vol > 0)) continue;
      std::array<double, 4> w;
      bool inside = true;
      for (int f = 0; f < 4 && inside; ++f) {
        const auto& l = kFaceLocal[f];
        w[f] = (x[l[1]] - x[l[0]]).cross(x[l[2]] - x[l[0]]).dot(c - x[l[0]]) / -vol;  // >= 0 inside
        inside = w[f] >= -1e-12;
      }
      if (!inside) continue;
      mark_on_segments(marks, insert_point(t, w), bits);
      break;
    }
  }
}

void CutStep::embed_segment(const Piece& piece, std::size_t si, SegmentMarks& marks) {
  const auto& seg = piece.boundary[si];
  std::vector<TetId> work(cand_.begin(), cand_.end());
  IdSet queued(in_cand_);
  // The cap only guards against degenerate input (the cut is then less exact, never
  // invalid); each real crossing makes one vertex.
  std::size_t splits = 0;
  const std::size_t max_splits = 64 + 2 * cand_.size();
  while (!work.empty() && splits < max_splits) {
    const TetId t = work.back();
    work.pop_back();
    queued.erase(t.idx());
    if (!mesh_.is_alive(t)) continue;
    for (int f = 0; f < 4; ++f) {
      const auto fv = mesh_.face_vertices(t, f);
      bool on_face = false;
      for (VertexId v : fv) {
        auto it = marks.find(v.idx());
        on_face |= it != marks.end() && (it->second & (1u << si));
      }
      if (on_face) continue;
      const Vec3 a = position(fv[0]), b = position(fv[1]), c = position(fv[2]);
      const int sp = orient3d(a, b, c, seg[0]), sq = orient3d(a, b, c, seg[1]);
      if (sp * sq >= 0) continue;
      const Vec3 n = (b - a).cross(c - a);
      const double vp = n.dot(seg[0] - a), vq = n.dot(seg[1] - a);
      const double s = std::clamp(vp / (vp - vq), 0.0, 1.0);
      const Vec3 x = seg[0] + s * (seg[1] - seg[0]);
      const auto w3 = triangle_barycentric(a, b, c, x);
      if (w3[0] < -1e-12 || w3[1] < -1e-12 || w3[2] < -1e-12) continue;
      std::array<double, 4> w{0, 0, 0, 0};
      for (int k = 0; k < 3; ++k) w[mesh_.local_index(t, fv[k])] = w3[k];
      const std::size_t before = mesh_.vertex_capacity(), alive_before = mesh_.num_vertices();
      const VertexId p = insert_point(t, w);
      mark_on_segments(marks, p, 1u << si);
      if (mesh_.num_vertices() != alive_before || mesh_.vertex_capacity() != before) {
        for (TetId x2 : mesh_.incident_tets(p))
          if (queued.insert(x2.idx()).second) work.push_back(x2);
        ++splits;
        break;
      }
    }
  }
}

int CutStep::side(const Piece& piece, std::size_t k, VertexId v) {
  if (on_piece_[k].count(v.idx())) return 0;
  auto it = side_cache_[k].find(v.idx());
  if (it != side_cache_[k].end()) return it->second;
  if (memory_) {
    auto m = memory_->side.find(v.idx());
    if (m != memory_->side.end()) return side_cache_[k][v.idx()] = m->second;
  }
  if (provisional_) {
    auto u = undecided_[k].find(v.idx());
    if (u != undecided_[k].end() && u->second == mesh_.counters().edits) return kUndecided;
  }
  const Vec3 x = position(v);
  int s = piece.side(x);
  const int exact = s;
  // Snap onto the plane only where the vertex's whole star is inside the piece: at the rim the
  // cut surface would otherwise pinch through the snapped vertex (two sheets touching at a
  // point, a non-manifold boundary once opened).
  const bool near = s != 0 && std::abs(piece.distance(x)) <= snap_length(v);
  if (near && memory_) {
    // A sheet: the vertex and its whole star project inside the swept polygon. The polygon only
    // grows, so once this holds it holds for good, and a single step over the whole motion
    // would say the same; while it does not, a provisional step waits for the blade to pass.
    bool inside = piece.contains(x, 0);
    for (TetId t : mesh_.incident_tets(v))
      for (VertexId w : mesh_.tet_vertices(t)) inside = inside && piece.contains(position(w), 0);
    // Snapping must not flatten a tet into the plane (all four vertices on the cut surface: the
    // faces beside it could then not say which side they are on, and would stay shut). Its
    // vertices are decided one by one, maybe steps apart, so the last one to decide keeps its side.
    bool flattens = false;
    for (TetId t : mesh_.incident_tets(v)) {
      int zero = 0;
      for (VertexId w : mesh_.tet_vertices(t)) {
        if (w == v) continue;
        auto m = memory_->side.find(w.idx());
        zero += on_piece_[k].count(w.idx()) || (m != memory_->side.end() && m->second == 0);
      }
      flattens = flattens || zero == 3;
    }
    if (inside && !flattens) s = 0;
    // At a sheet's finish whose front becomes the next sheet's crease: a vertex this close to
    // the front too (kCreaseFrontShare of the snap distance) is on the sheet. Left on its side,
    // its edges across the plane were split a hair from it, and the tets between it, those
    // splits and the crease stayed shut across both sheets (an S across the organ stayed in
    // one piece so; docs/cut.md#curved-paths). Its star reaches past the front, but the next
    // sheet goes on from there, so the cut does not pinch through it.
    else if (!inside && !provisional_ && !flattens && near_crease_front(x, kCreaseFrontShare * snap_length(v))) s = 0;
    else if (!inside && provisional_) {
      undecided_[k][v.idx()] = mesh_.counters().edits;
      return kUndecided;
    }
    // The sheet's finish, its boundary embedded: a vertex inside the swept polygon whose star
    // reaches past its rim (the blade's sides and last front inside the body) snaps too. Kept
    // on its side, the edges it has across the plane were split a hair from it, and the
    // slivers there had both ends of their short edge on the boundary once the cut opened: no
    // contraction may join them (docs/cut.md#the-defaults). Its cut faces lie inside the
    // polygon, so the rim stays where it was.
    // A vertex of an earlier cut cannot move (its cut face would leave its plane); it is put on
    // the sheet where it is, the new cut bending through it by at most the snap distance:
    // otherwise the slivers beside it have a short interior edge between two cut vertices,
    // which the link condition forbids contracting. A vertex of the body's surface is put on
    // the sheet only within kSurfaceSnapFraction of the snap distance (see there).
    else if (!flattens && piece.contains(x, 0) &&
             (move_snapped(piece, k, v) || on_cut_only(mesh_, v) ||
              std::abs(piece.distance(x)) <= kSurfaceSnapFraction * snap_length(v)))
      s = 0;
  } else if (near && piece.contains(x, 0) && piece.boundary_distance(x) > star_radius(v)) {
    s = 0;
  }
  // A boundary vertex whose boundary neighbours all lie clearly on one side of the plane: the
  // plane only touches the surface there. Put on it, the vertex would be the one point where
  // the sheet meets the surface, and opening the cut would pinch the boundary there: its faces
  // would stay shut, a hole in the cut the size of its star (separate.cpp). It keeps its side.
  if (s == 0 && exact != 0 && !on_piece_[k].count(v.idx()) && touches_surface_only(piece, v)) s = exact;
  // Snapped: moved onto the plane where it may (cut/snap_move.h), so the cut surface stays flat.
  if (s == 0 && exact != 0 && !on_piece_[k].count(v.idx())) move_snapped(piece, k, v);
  decide(k, v, s);
  return s;
}

bool CutStep::touches_surface_only(const Piece& piece, VertexId v) {
  int sign = 0;
  bool boundary = false;
  for (TetId t : mesh_.incident_tets(v))
    for (int f = 0; f < 4; ++f) {
      if (mesh_.tet_vertices(t)[f] == v || mesh_.neighbor(t, f).is_valid()) continue;
      boundary = true;
      for (VertexId w : mesh_.face_vertices(t, f)) {
        if (w == v) continue;
        const double d = piece.distance(position(w));
        if (!(std::abs(d) > snap_length(w))) return false;  // may be on the plane: the sheet crosses the surface
        const int o = d > 0 ? 1 : -1;
        if (sign != 0 && o != sign) return false;
        sign = o;
      }
    }
  return boundary;
}

bool CutStep::near_crease_front(const Vec3& x, double reach) const {
  return crease_front_ && beside_segment(x, (*crease_front_)[0], (*crease_front_)[1], reach);
}

bool CutStep::move_snapped(const Piece& piece, std::size_t k, VertexId v) {
  if (no_moves_) return false;
  const auto p = move_onto_plane(mesh_, v, piece, [this](VertexId w) { return position(w); }, fixed_);
  if (!p) return false;
  created_pos_[v.idx()] = *p;
  on_piece_[k].insert(v.idx());
  return true;
}

// Snapping must not flatten a whole tet into the plane: the cut surface could then not say
// which side the tet is on, and would leave a hole there. Such a tet gets its farthest snapped
// vertex back on its exact side.
void CutStep::pin_flattened(const Piece& piece, IdSet& pinned) {
  const std::size_t k = current_piece_;
  for (std::size_t i = 0; i < cand_.size(); ++i) {
    const TetId t = cand_[i];
    if (!mesh_.is_alive(t)) continue;
    const auto& tv = mesh_.tet_vertices(t);
    if (side(piece, k, tv[0]) || side(piece, k, tv[1]) || side(piece, k, tv[2]) || side(piece, k, tv[3])) continue;
    int far = -1;
    double far_d = -1;
    for (int j = 0; j < 4; ++j) {
      if (on_piece_[k].count(tv[j].idx())) continue;
      const double d = std::abs(piece.distance(position(tv[j])));
      if (d > far_d) {
        far_d = d;
        far = j;
      }
    }
    if (far >= 0 && pinned.insert(tv[far].idx()).second) decide(k, tv[far], piece.side(position(tv[far])));
  }
}

// The edges of the candidate tets that cross the piece, where each tet's section lies inside
// it; a crossing too close to an endpoint (or one whose split would make a flat tet) puts that
// endpoint on the plane instead. Returns whether such a decision changed a side (the caller
// then collects again).
bool CutStep::collect_crossings(const Piece& piece, IdSet& pinned,
                                std::map<std::pair<std::uint32_t, std::uint32_t>, EdgeSplit>& edges) {
  const std::size_t k = current_piece_;
  bool changed = false;
  std::vector<EdgeSplit> crossing;
  for (std::size_t i = 0; i < cand_.size(); ++i) {
    const TetId t = cand_[i];
    if (!mesh_.is_alive(t)) continue;
    const auto& tv = mesh_.tet_vertices(t);
    int s[4];
    bool plus = false, minus = false, undecided = false;
    for (int j = 0; j < 4; ++j) {
      s[j] = side(piece, k, tv[j]);
      undecided |= s[j] == kUndecided;
      plus |= s[j] == 1;
      minus |= s[j] < 0;
    }
    if (undecided || !(plus && minus)) continue;
    // The tet's section with the plane; after the boundary is embedded it lies wholly inside
    // or wholly outside the piece, so its centroid decides. A provisional step has not
    // embedded the front: the whole section must be inside (the blade has left the tet).
    Vec3 c = Vec3::Zero();
    int n = 0;
    bool all_inside = true;
    crossing.clear();
    for (int a = 0; a < 4; ++a) {
      if (s[a] == 0) {
        c += position(tv[a]);
        ++n;
        all_inside = all_inside && piece.contains(position(tv[a]), kInsideTol);
      }
      for (int b = a + 1; b < 4; ++b) {
        if (s[a] * s[b] >= 0) continue;
        const Vec3 xa = position(tv[a]), xb = position(tv[b]);
        const double da = piece.distance(xa), db = piece.distance(xb);
        double u = (da - db) != 0 ? da / (da - db) : 0.5;
        // A crossing this close to an endpoint would make a flat tet: the endpoint is on the
        // plane instead (the snap floor, relative to this edge).
        const int near = u < kSnapFloor ? a : (u > 1 - kSnapFloor ? b : -1);
        if (near >= 0) {
          if (!on_piece_[k].count(tv[near].idx()) && pinned.insert(tv[near].idx()).second) {
            decide(k, tv[near], 0);
            changed = true;
          }
          // Pinned to its side already (the farthest vertex of a tet snapping would flatten):
          // a split this close to it would make a vertex within rounding of it and tets of no
          // volume (docs/cut.md#known-gaps), so the edge is not split, as below.
          continue;
        }
        if (!edge_split_ok_cached(tv[a], tv[b], u)) {
          const int nv = u < 0.5 ? a : b;
          if (!on_piece_[k].count(tv[nv].idx()) && pinned.insert(tv[nv].idx()).second) {
            decide(k, tv[nv], 0);
            changed = true;
          }
          continue;  // not split: this tet's section stays uncut (rare, on near-flat tets only)
        }
        c += (1 - u) * xa + u * xb;
        ++n;
        all_inside = all_inside && piece.contains((1 - u) * xa + u * xb, kInsideTol);
        crossing.push_back({tv[a], tv[b], u});
      }
    }
    if (provisional_ ? !all_inside : !piece.contains(c / n, kInsideTol)) continue;
    for (const EdgeSplit& e : crossing) {
      edges.emplace(std::make_pair(std::min(e.a.idx(), e.b.idx()), std::max(e.a.idx(), e.b.idx())), e);
    }
  }
  return changed;
}

// Whether tet t's section with the piece lies wholly inside it (every side decided).
bool CutStep::section_inside(const Piece& piece, TetId t) {
  const std::size_t k = current_piece_;
  const auto& tv = mesh_.tet_vertices(t);
  int sd[4];
  for (int j = 0; j < 4; ++j)
    if ((sd[j] = side(piece, k, tv[j])) == kUndecided) return false;
  for (int a = 0; a < 4; ++a) {
    if (sd[a] == 0 && !piece.contains(position(tv[a]), kInsideTol)) return false;
    for (int b = a + 1; b < 4; ++b) {
      if (sd[a] * sd[b] >= 0) continue;
      const Vec3 xa = position(tv[a]), xb = position(tv[b]);
      const double da = piece.distance(xa), db = piece.distance(xb);
      const double u = std::clamp((da - db) != 0 ? da / (da - db) : 0.5, 0.0, 1.0);
      if (!piece.contains((1 - u) * xa + u * xb, kInsideTol)) return false;
    }
  }
  return true;
}

void CutStep::split_crossings(const Piece& piece) {
  const std::size_t k = current_piece_;
  std::map<std::pair<std::uint32_t, std::uint32_t>, EdgeSplit> edges;
  // Vertices whose side one of the two corrections set; each vertex changes at most once, so
  // the passes end.
  IdSet pinned;
  for (bool changed = true; changed;) {
    edges.clear();
    pin_flattened(piece, pinned);
    changed = collect_crossings(piece, pinned, edges);
  }
  // A provisional step splits an edge only when every tet around it is committable: a split
  // point made for one tet lands in all the others, and one near the sheet's rim, in a tet that
  // still straddles the rim, keeps a single star component there for good (its cut faces then
  // pinch and stay shut; a single step over the motion splits such edges only after the rim
  // is embedded).
  for (const auto& [key, e] : edges) {
    if (!mesh_.is_alive(e.a) || !mesh_.is_alive(e.b)) continue;
    if (provisional_) {
      bool all = true;
      for (TetId x : mesh_.incident_tets(e.a))
        if (mesh_.local_index(x, e.b) >= 0) all = all && section_inside(piece, x);
      if (!all) continue;
    }
    bool exists = false;
    for (TetId x : mesh_.incident_tets(e.a))
      if (mesh_.local_index(x, e.b) >= 0) {
        exists = true;
        note_destroyed(x);
      }
    if (!exists || !edge_split_ok(e.a, e.b, e.s)) continue;
    pending_radius_ = kSnapFloor * (position(e.a) - position(e.b)).norm();
    const VertexId p = mesh_.split_edge(e.a, e.b, e.s);
    created_pos_[p.idx()] = (1 - e.s) * position(e.a) + e.s * position(e.b);
    on_piece_[k].insert(p.idx());
    if (memory_) memory_->side[p.idx()] = 0;
    note_new_vertex(p);
  }
}

std::vector<CutFacePair> CutStep::cut_faces(std::span<const Piece> pieces) {
  std::vector<CutFacePair> out;
  IdSet done;
  for (std::size_t k = 0; k < pieces.size(); ++k) {
    const Piece& piece = pieces[k];
    for (std::size_t i = 0; i < cand_.size(); ++i) {
      const TetId t = cand_[i];
      if (!mesh_.is_alive(t)) continue;
      const auto& tv = mesh_.tet_vertices(t);
      for (int f = 0; f < 4; ++f) {
        const TetId n = mesh_.neighbor(t, f);
        if (!n.is_valid() || done.count(face_key(t, f))) continue;
        const auto fv = mesh_.face_vertices(t, f);
        if (side(piece, k, fv[0]) != 0 || side(piece, k, fv[1]) != 0 || side(piece, k, fv[2]) != 0) continue;
        if (provisional_ && !(piece.contains(position(fv[0]), kInsideTol) &&
                              piece.contains(position(fv[1]), kInsideTol) &&
                              piece.contains(position(fv[2]), kInsideTol)))
          continue;
        const int g = shared_face(mesh_, n, t);
        if (g < 0) continue;
        const int sa = side(piece, k, tv[f]), sb = side(piece, k, mesh_.tet_vertices(n)[g]);
        if (sa == kUndecided || sb == kUndecided || sa * sb >= 0) continue;  // a flat tet lying in the plane: the cut goes around it
        const Vec3 c = (position(fv[0]) + position(fv[1]) + position(fv[2])) / 3;
        if (!piece.contains(c, kInsideTol)) continue;
        done.insert(face_key(t, f));
        done.insert(face_key(n, g));
        out.push_back({{t, f}, {n, g}});
      }
    }
  }
  return out;
}

std::vector<CutFacePair> CutStep::crease_faces(const CreaseSides& prev, const CreaseSides& next, const Vec3& fa,
                                               const Vec3& fb, std::span<const TetId> around) const {
  // Across the crease, in-plane: away from the previous sheet and into the next one. Their sum
  // is the normal of the plane that halves the angle between the two sheets at the crease: a
  // point on the previous sheet's side of it takes that sheet's side, the others the next's.
  const Vec3 f = (fb - fa).normalized();
  Vec3 u_prev = prev.piece.normal.cross(f), u_next = next.piece.normal.cross(f);
  auto inner = [](const Piece& p) {
    Vec3 c = Vec3::Zero();
    for (const CutTriangle& t : p.triangles) c += (t.p[0] + t.p[1] + t.p[2]) / 3;
    return Vec3(c / double(std::max<std::size_t>(p.triangles.size(), 1)));
  };
  if (u_prev.dot(inner(prev.piece) - fa) > 0) u_prev = -u_prev;
  if (u_next.dot(inner(next.piece) - fa) < 0) u_next = -u_next;
  const Vec3 w = u_prev + u_next;
  auto behind = [&](const Vec3& x) { return w.dot(x - fa) < 0; };
  // At the crease itself (a face whose corners lie along it, within the snap distance): on the
  // edge of both polygons, where a corner a hair off the crease line puts it a hair outside
  // either (in the wedge between their planes); it is inside the union.
  auto on_crease = [&](const Vec3& x, double reach) { return beside_segment(x, fa, fb, reach); };
  // A vertex a sheet decided keeps that side (snapped: 0); one it did not decide is on the side
  // its position says (exact).
  auto side = [&](VertexId v) {
    const Vec3 x = position(v);
    const bool b = behind(x);
    const CreaseSides& s = b ? prev : next;
    auto it = s.sides.find(v.idx());
    if (it != s.sides.end()) return it->second;
    // A vertex the other sheet put on itself, within this sheet's snap distance of it, is on
    // the union: near the crease the two sheets are that close, and a hair's side of this
    // one would leave a flat tet between them joined to both sides.
    const CreaseSides& o = b ? next : prev;
    auto jt = o.sides.find(v.idx());
    if (jt != o.sides.end() && jt->second == 0 && std::abs(s.piece.distance(x)) <= snap_ * mean_incident_edge(v)) return 0;
    return s.piece.side(x);
  };
  // The side of a tet beside a face on the union: its apex's; where the apex is on the union
  // too, another vertex's; where all four are (a wedge between the two sheets at the crease),
  // its centroid's.
  auto tet_side = [&](TetId t, VertexId apex) {
    int s = side(apex);
    if (s != 0) return s;
    for (VertexId v : mesh_.tet_vertices(t)) {
      const int o = side(v);
      if (o == kUndecided || (o != 0 && s != 0 && o != s)) return kUndecided;
      if (o != 0) s = o;
    }
    if (s != 0) return s;
    const auto x = tet_positions(t);
    const Vec3 c = (x[0] + x[1] + x[2] + x[3]) / 4;
    return (behind(c) ? prev : next).piece.side(c);
  };
  std::vector<CutFacePair> out;
  IdSet done;
  auto scan = [&](TetId t) {
    if (!mesh_.is_alive(t)) return;
    const auto& tv = mesh_.tet_vertices(t);
    for (int f = 0; f < 4; ++f) {
      const TetId n = mesh_.neighbor(t, f);
      if (!n.is_valid() || done.count(face_key(t, f))) continue;
      const auto fv = mesh_.face_vertices(t, f);
      if (side(fv[0]) != 0 || side(fv[1]) != 0 || side(fv[2]) != 0) continue;
      const int g = shared_face(mesh_, n, t);
      if (g < 0) continue;
      const int sa = tet_side(t, tv[f]), sb = tet_side(n, mesh_.tet_vertices(n)[g]);
      if (sa == kUndecided || sb == kUndecided || sa * sb >= 0) continue;
      const Vec3 c = (position(fv[0]) + position(fv[1]) + position(fv[2])) / 3;
      if (!(behind(c) ? prev : next).piece.contains(c, kInsideTol)) {
        double longest = 0;
        for (int i = 0; i < 3; ++i) longest = std::max(longest, (position(fv[i]) - position(fv[(i + 1) % 3])).norm());
        if (!on_crease(c, snap_ * longest)) continue;
      }
      done.insert(face_key(t, f));
      done.insert(face_key(n, g));
      out.push_back({{t, f}, {n, g}});
    }
  };
  for (TetId t : around) scan(t);
  return out;
}

void CutStep::add_known_segment(const Vec3& a, const Vec3& b, std::vector<VertexId> vertices) {
  embedded_.push_back({a, b, std::move(vertices)});
}

bool CutStep::on_segment(VertexId v, const Vec3& a, const Vec3& b) const {
  if (!mesh_.is_alive(v)) return false;
  // A point embedded on the segment lies on it up to rounding, or up to the snap distance
  // where it snapped onto a vertex; an id the mesh has given to another vertex since does not.
  const Vec3 x = position(v), d = b - a;
  const double t = std::clamp((x - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
  return (x - (a + t * d)).norm() <= 2 * snap_ * mean_incident_edge(v) + 1e-9 * d.norm();
}

double CutStep::mean_incident_edge(VertexId v) const {
  const Vec3 x = position(v);
  double sum = 0;
  int n = 0;
  for (TetId t : mesh_.incident_tets(v))
    for (VertexId w : mesh_.tet_vertices(t))
      if (w != v) {
        sum += (position(w) - x).norm();
        ++n;
      }
  return n ? sum / n : 0.0;
}

std::vector<VertexId> CutStep::on_segment(std::span<const VertexId> vertices, const Vec3& a, const Vec3& b) const {
  std::vector<VertexId> out;
  for (VertexId v : vertices)
    if (on_segment(v, a, b)) out.push_back(v);
  return out;
}

std::vector<VertexId> CutStep::segment_vertices(const Vec3& a, const Vec3& b) const {
  for (const EmbeddedSegment& e : embedded_)
    if ((e.a == a && e.b == b) || (e.a == b && e.b == a)) return on_segment(e.vertices, a, b);
  return {};
}

std::vector<TetId> CutStep::live_candidates() const {
  std::vector<TetId> out;
  for (TetId t : cand_)
    if (mesh_.is_alive(t)) out.push_back(t);
  return out;
}

}  // namespace incise::cut_detail
