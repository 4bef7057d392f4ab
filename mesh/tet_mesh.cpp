// TetMesh storage, incidence upkeep, batches, compaction and validation.
// The refinement and flip operations live in tet_mesh_edits.cpp.
#include "mesh/tet_mesh.h"

#include <algorithm>
#include <atomic>
#include <limits>
#include <map>
#include <sstream>
#include <unordered_map>

#include <Eigen/Dense>

#include "mesh/errors.h"

namespace incise {

namespace {
std::string vid(VertexId v) { return "vertex " + std::to_string(v.idx()); }
std::string tid(TetId t) { return "tet " + std::to_string(t.idx()); }

template <class T>
void erase_one(std::vector<T>& v, T x) {
  auto it = std::find(v.begin(), v.end(), x);
  if (it != v.end()) {
    *it = v.back();
    v.pop_back();
  }
}
}  // namespace

std::vector<VertexId> TetMesh::vertices() const {
  std::vector<VertexId> out;
  out.reserve(num_vertices());
  for (std::uint32_t i = 0; i < rest_.size(); ++i)
    if (vertex_alive_[i]) out.emplace_back(i);
  return out;
}

std::vector<TetId> TetMesh::tets() const {
  std::vector<TetId> out;
  out.reserve(num_tets());
  for (std::uint32_t i = 0; i < tet_v_.size(); ++i)
    if (tet_alive_[i]) out.emplace_back(i);
  return out;
}

std::array<VertexId, 3> TetMesh::face_vertices(TetId t, int f) const {
  const auto& v = tet_v_[t.idx()];
  return {v[kFaceLocal[f][0]], v[kFaceLocal[f][1]], v[kFaceLocal[f][2]]};
}

int TetMesh::local_index(TetId t, VertexId v) const {
  const auto& tv = tet_v_[t.idx()];
  for (int i = 0; i < 4; ++i)
    if (tv[i] == v) return i;
  return -1;
}

double TetMesh::signed_volume(const std::array<VertexId, 4>& v) const {
  const Vec3& p0 = rest_[v[0].idx()];
  Eigen::Matrix3d m;
  m.col(0) = rest_[v[1].idx()] - p0;
  m.col(1) = rest_[v[2].idx()] - p0;
  m.col(2) = rest_[v[3].idx()] - p0;
  return m.determinant() / 6.0;
}

double TetMesh::volume(TetId t) const { return signed_volume(tet_v_[t.idx()]); }

double TetMesh::total_volume() const {
  double sum = 0;
  for (std::uint32_t i = 0; i < tet_v_.size(); ++i)
    if (tet_alive_[i]) sum += volume(TetId(i));
  return sum;
}

std::vector<BoundaryFace> TetMesh::boundary_faces() const {
  std::vector<BoundaryFace> out;
  for (std::uint32_t i = 0; i < tet_v_.size(); ++i) {
    if (!tet_alive_[i]) continue;
    for (int f = 0; f < 4; ++f)
      if (!tet_n_[i][f].is_valid()) out.push_back({TetId(i), f, face_vertices(TetId(i), f), face_tag_[i][f]});
  }
  return out;
}

TetMesh::EdgeStar TetMesh::edge_star(VertexId a, VertexId b) const {
  EdgeStar star;
  struct Wedge {
    TetId t;
    VertexId c, d;
  };
  std::vector<Wedge> wedges;
  for (TetId t : vertex_tets_[a.idx()]) {
    ++const_cast<EditCounters&>(counters_).visits;
    const auto& v = tet_v_[t.idx()];
    int ia = -1, ib = -1;
    for (int i = 0; i < 4; ++i) {
      if (v[i] == a) ia = i;
      if (v[i] == b) ib = i;
    }
    if (ib < 0) continue;
    int rest[2], k = 0;
    for (int i = 0; i < 4; ++i)
      if (i != ia && i != ib) rest[k++] = i;
    // Parity of the permutation (ia, ib, rest0, rest1): (a,b,c,d) has t's orientation
    // exactly when it is even.
    int perm[4] = {ia, ib, rest[0], rest[1]};
    int inversions = 0;
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j)
        if (perm[i] > perm[j]) ++inversions;
    VertexId c = v[rest[0]], d = v[rest[1]];
    if (inversions % 2) std::swap(c, d);
    wedges.push_back({t, c, d});
  }
  if (wedges.empty()) return star;
  // Find an open start: a c that is no wedge's d.
  std::size_t start = 0;
  bool open = false;
  for (std::size_t i = 0; i < wedges.size() && !open; ++i) {
    bool is_d = false;
    for (const auto& w : wedges) is_d |= (w.d == wedges[i].c);
    if (!is_d) {
      start = i;
      open = true;
    }
  }
  std::vector<std::uint8_t> used(wedges.size(), 0);
  std::size_t cur = start;
  star.ring.push_back(wedges[cur].c);
  for (std::size_t step = 0; step < wedges.size(); ++step) {
    used[cur] = 1;
    star.tets.push_back(wedges[cur].t);
    VertexId next = wedges[cur].d;
    std::size_t nxt = wedges.size();
    for (std::size_t i = 0; i < wedges.size(); ++i)
      if (!used[i] && wedges[i].c == next) nxt = i;
    if (nxt == wedges.size()) {
      if (step + 1 != wedges.size())
        throw InvalidMesh("edge (" + std::to_string(a.idx()) + "," + std::to_string(b.idx()) +
                          ") has a non-manifold star");
      if (open) star.ring.push_back(next);
      star.closed = !open && next == star.ring.front();
      if (!open && !star.closed)
        throw InvalidMesh("edge (" + std::to_string(a.idx()) + "," + std::to_string(b.idx()) +
                          ") star does not close");
      break;
    }
    star.ring.push_back(next);
    cur = nxt;
  }
  return star;
}

void TetMesh::reserve(std::size_t nv, std::size_t nt) {
  rest_.reserve(nv);
  vertex_alive_.reserve(nv);
  vertex_tets_.reserve(nv);
  touched_mark_.reserve(nv);
  tet_v_.reserve(nt);
  tet_n_.reserve(nt);
  face_tag_.reserve(nt);
  label_.reserve(nt);
  tet_alive_.reserve(nt);
}

void TetMesh::touch(VertexId v) {
  if (!touched_mark_[v.idx()]) {
    touched_mark_[v.idx()] = 1;
    pending_touched_.push_back(v);
  }
  pending_.any = true;
}

VertexId TetMesh::add_vertex(const Vec3& p) {
  VertexId v;
  if (!free_vertices_.empty()) {
    v = free_vertices_.back();
    free_vertices_.pop_back();
    rest_[v.idx()] = p;
    vertex_alive_[v.idx()] = 1;
    vertex_tets_[v.idx()].clear();
  } else {
    v = VertexId(static_cast<std::uint32_t>(rest_.size()));
    rest_.push_back(p);
    vertex_alive_.push_back(1);
    vertex_tets_.emplace_back();
    touched_mark_.push_back(0);
  }
  ++vertex_alive_count_;
  if (logging_) log_.vertices.push_back(v);
  return v;
}

VertexId TetMesh::add_vertex_interpolated(std::span<const VertexId> parents, std::span<const double> weights) {
  if (parents.empty() || parents.size() > 4 || parents.size() != weights.size())
    throw InvalidArgument("add_vertex_interpolated: need 1 to 4 parents with one weight each");
  Vec3 p = Vec3::Zero();
  VertexOrigin o;
  for (std::size_t k = 0; k < parents.size(); ++k) {
    if (!is_alive(parents[k])) throw InvalidArgument("add_vertex_interpolated: parent " + vid(parents[k]) + " is dead");
    p += weights[k] * rest_[parents[k].idx()];
    o.parents[k] = parents[k];
    o.weights[k] = weights[k];
  }
  o.vertex = add_vertex(p);
  pending_vertices_.push_back(o);
  pending_.any = true;
  return o.vertex;
}

void TetMesh::move_vertex(VertexId v, std::span<const VertexId> parents, std::span<const double> weights) {
  if (!is_alive(v)) throw InvalidArgument("move_vertex: " + vid(v) + " is not alive");
  if (parents.empty() || parents.size() > 4 || parents.size() != weights.size())
    throw InvalidArgument("move_vertex: need 1 to 4 parents with one weight each");
  ++counters_.edits;
  Vec3 p = Vec3::Zero();
  VertexOrigin o;
  o.vertex = v;
  for (std::size_t k = 0; k < parents.size(); ++k) {
    if (!is_alive(parents[k])) throw InvalidArgument("move_vertex: parent " + vid(parents[k]) + " is dead");
    p += weights[k] * rest_[parents[k].idx()];
    o.parents[k] = parents[k];
    o.weights[k] = weights[k];
  }
  batch_origin_.try_emplace(v.idx(), rest_[v.idx()]);
  if (logging_) log_.moved = true;
  rest_[v.idx()] = p;
  pending_moved_.push_back(o);
  // The tets' rest shapes changed: consumers must rebuild their per-tet data.
  for (TetId t : vertex_tets_[v.idx()]) {
    ++counters_.visits;
    events_.push_back({Event::RemoveTet, t});
    events_.push_back({Event::AddTet, t});
    for (VertexId x : tet_v_[t.idx()]) touch(x);
  }
  touch(v);
}

bool TetMesh::is_move_ok(VertexId v, const Vec3& p, double min_volume_fraction) const {
  if (!is_alive(v)) return false;
  for (TetId t : vertex_tets_[v.idx()]) {
    std::array<Vec3, 4> x;
    for (int k = 0; k < 4; ++k) x[k] = rest_[tet_v_[t.idx()][k].idx()];
    const double before = (x[1] - x[0]).dot((x[2] - x[0]).cross(x[3] - x[0]));
    x[local_index(t, v)] = p;
    const double after = (x[1] - x[0]).dot((x[2] - x[0]).cross(x[3] - x[0]));
    if (!(after > 0) || after < min_volume_fraction * before) return false;
  }
  return true;
}

void TetMesh::remove_vertex(VertexId v) {
  if (!is_alive(v)) throw InvalidArgument("remove_vertex: " + vid(v) + " is not alive");
  if (!vertex_tets_[v.idx()].empty()) throw InvalidMesh("remove_vertex: " + vid(v) + " is still used by tets");
  vertex_alive_[v.idx()] = 0;
  --vertex_alive_count_;
  // Listed as removed even when this batch added it: its added record stays, since later
  // records of the batch may name it as a parent (consumers apply removals last). Its id is
  // reused only after the batch, so one id never stands for two vertices in one record.
  pending_removed_vertices_.push_back(v);
  pending_.any = true;
}

void TetMesh::link_faces(TetId t) {
  const auto& tv = tet_v_[t.idx()];
  for (int f = 0; f < 4; ++f) {
    if (tet_n_[t.idx()][f].is_valid()) continue;
    VertexId x = tv[kFaceLocal[f][0]], y = tv[kFaceLocal[f][1]], z = tv[kFaceLocal[f][2]];
    // Every tet with the face is around each of its vertices: look around the one with fewest.
    const std::vector<TetId>* around = &vertex_tets_[x.idx()];
    for (VertexId w : {y, z})
      if (vertex_tets_[w.idx()].size() < around->size()) around = &vertex_tets_[w.idx()];
    for (TetId u : *around) {
      ++counters_.visits;
      if (u == t) continue;
      const auto& uv = tet_v_[u.idx()];
      int hits = 0, missing = -1;
      for (int i = 0; i < 4; ++i) {
        if (uv[i] == x || uv[i] == y || uv[i] == z)
          ++hits;
        else
          missing = i;
      }
      if (hits != 3) continue;
      if (tet_n_[u.idx()][missing].is_valid() && tet_n_[u.idx()][missing] != t)
        throw InvalidMesh("face (" + std::to_string(x.idx()) + "," + std::to_string(y.idx()) + "," +
                          std::to_string(z.idx()) + ") would be shared by more than two tets");
      tet_n_[t.idx()][f] = u;
      tet_n_[u.idx()][missing] = t;
      face_tag_[t.idx()][f] = kTagNone;
      face_tag_[u.idx()][missing] = kTagNone;
    }
  }
}

void TetMesh::unlink_tet(TetId t) {
  for (int f = 0; f < 4; ++f) {
    TetId u = tet_n_[t.idx()][f];
    if (!u.is_valid()) continue;
    for (int g = 0; g < 4; ++g) {
      ++counters_.visits;
      if (tet_n_[u.idx()][g] == t) {
        tet_n_[u.idx()][g] = TetId();
        face_tag_[u.idx()][g] = kTagNone;
      }
    }
    tet_n_[t.idx()][f] = TetId();
  }
  for (VertexId v : tet_v_[t.idx()]) {
    counters_.visits += vertex_tets_[v.idx()].size();
    erase_one(vertex_tets_[v.idx()], t);
  }
}

TetId TetMesh::add_tet(VertexId a, VertexId b, VertexId c, VertexId d, int label) {
  ++counters_.edits;
  std::array<VertexId, 4> v{a, b, c, d};
  for (int i = 0; i < 4; ++i) {
    if (!is_alive(v[i])) throw InvalidMesh("add_tet: " + vid(v[i]) + " is not a live vertex");
    for (int j = 0; j < i; ++j)
      if (v[i] == v[j]) throw InvalidMesh("add_tet: " + vid(v[i]) + " repeated");
  }
  TetId t;
  if (!free_tets_.empty()) {
    t = free_tets_.back();
    free_tets_.pop_back();
  } else {
    t = TetId(static_cast<std::uint32_t>(tet_v_.size()));
    tet_v_.emplace_back();
    tet_n_.emplace_back();
    face_tag_.emplace_back();
    label_.push_back(0);
    tet_alive_.push_back(0);
  }
  tet_v_[t.idx()] = v;
  tet_n_[t.idx()] = {TetId(), TetId(), TetId(), TetId()};
  face_tag_[t.idx()] = {kTagNone, kTagNone, kTagNone, kTagNone};
  label_[t.idx()] = label;
  for (VertexId x : v) vertex_tets_[x.idx()].push_back(t);
  try {
    link_faces(t);
  } catch (...) {
    unlink_tet(t);
    free_tets_.push_back(t);
    throw;
  }
  tet_alive_[t.idx()] = 1;
  ++tet_alive_count_;
  if (logging_ && log_added_.insert(t.idx()).second) log_.added.push_back(t);
  events_.push_back({Event::AddTet, t});
  for (VertexId x : v) touch(x);
  return t;
}

void TetMesh::remove_tet(TetId t) {
  if (!is_alive(t)) throw InvalidArgument("remove_tet: " + tid(t) + " is not alive");
  ++counters_.edits;
  if (logging_) log_before_rewrite(t);
  unlink_tet(t);
  tet_alive_[t.idx()] = 0;
  --tet_alive_count_;
  free_tets_.push_back(t);
  events_.push_back({Event::RemoveTet, t});
  for (VertexId x : tet_v_[t.idx()]) touch(x);
}

void TetMesh::replace_vertex(TetId t, VertexId old_v, VertexId new_v) {
  int i = local_index(t, old_v);
  if (i < 0) throw InvalidArgument("replace_vertex: " + vid(old_v) + " is not in " + tid(t));
  if (!is_alive(new_v) || local_index(t, new_v) >= 0)
    throw InvalidArgument("replace_vertex: " + vid(new_v) + " is dead or already in " + tid(t));
  ++counters_.edits;
  if (logging_) {
    log_before_rewrite(t);
    if (log_added_.insert(t.idx()).second) log_.added.push_back(t);
  }
  auto tags = face_tag_[t.idx()];
  unlink_tet(t);
  events_.push_back({Event::RemoveTet, t});
  touch(old_v);
  tet_v_[t.idx()][i] = new_v;
  for (VertexId x : tet_v_[t.idx()]) vertex_tets_[x.idx()].push_back(t);
  link_faces(t);
  for (int f = 0; f < 4; ++f)
    if (!tet_n_[t.idx()][f].is_valid()) face_tag_[t.idx()][f] = tags[f];
  events_.push_back({Event::AddTet, t});
  for (VertexId x : tet_v_[t.idx()]) touch(x);
}

void TetMesh::log_before_rewrite(TetId t) {
  if (log_added_.count(t.idx()) || !log_saved_.insert(t.idx()).second) return;
  log_.saved.push_back({t, tet_v_[t.idx()], face_tag_[t.idx()], label_[t.idx()]});
}

void TetMesh::begin_undo_log() {
  logging_ = true;
  log_ = UndoLog{};
  log_added_.clear();
  log_saved_.clear();
}

TetMesh::UndoLog TetMesh::end_undo_log() {
  logging_ = false;
  for (TetId t : log_.added)
    if (tet_alive_[t.idx()]) log_.pieces.emplace_back(t, tet_v_[t.idx()]);
  log_added_.clear();
  log_saved_.clear();
  return std::move(log_);
}

bool TetMesh::can_undo(const UndoLog& log) const {
  if (log.moved) return false;
  for (const auto& [t, v] : log.pieces)
    if (!is_alive(t) || tet_v_[t.idx()] != v) return false;
  for (VertexId v : log.vertices)
    if (!is_alive(v)) return false;
  return true;
}

std::vector<std::pair<TetId, TetId>> TetMesh::undo(const UndoLog& log) {
  if (log.moved) throw InvalidArgument("undo: the logged edits moved a vertex");
  if (!can_undo(log)) throw InvalidArgument("undo: the logged edits' tets were edited since");
  for (TetId t : log.added)
    if (is_alive(t)) remove_tet(t);
  std::vector<std::pair<TetId, TetId>> ids;
  ids.reserve(log.saved.size());
  for (const UndoLog::SavedTet& s : log.saved) {
    const auto& v = s.vertices;
    const TetId t = add_tet(v[0], v[1], v[2], v[3], s.label);
    for (int f = 0; f < 4; ++f)
      if (!tet_n_[t.idx()][f].is_valid()) face_tag_[t.idx()][f] = s.tags[f];
    ids.emplace_back(s.id, t);
  }
  for (VertexId v : log.vertices)
    if (is_alive(v)) remove_vertex(v);
  return ids;
}

std::vector<TetId> TetMesh::pending_added_tets() const {
  // In take_change()'s order: by each id's first event.
  std::vector<TetId> out;
  IdMap<bool> added;  // id -> any add event
  std::vector<std::uint32_t> order;
  for (const Event& e : events_) {
    auto [it, inserted] = added.try_emplace(e.tet.idx(), false);
    if (inserted) order.push_back(e.tet.idx());
    it->second = it->second || e.kind == Event::AddTet;
  }
  for (std::uint32_t id : order)
    if (added[id] && tet_alive_[id]) out.emplace_back(id);
  return out;
}

TopologyChange TetMesh::take_change() {
  TopologyChange ch;
  struct State {
    bool existed_before = false, any_remove = false, any_add = false;
    std::size_t order = 0;
  };
  IdMap<State> st;
  st.reserve(events_.size());
  std::vector<std::uint32_t> order;
  for (const Event& e : events_) {
    auto [it, inserted] = st.try_emplace(e.tet.idx());
    if (inserted) {
      it->second.existed_before = (e.kind == Event::RemoveTet);
      order.push_back(e.tet.idx());
    }
    (e.kind == Event::RemoveTet ? it->second.any_remove : it->second.any_add) = true;
  }
  for (std::uint32_t id : order) {
    const State& s = st[id];
    if (s.existed_before && s.any_remove) ch.removed_tets.emplace_back(id);
    if (tet_alive_[id] && s.any_add) ch.added_tets.emplace_back(id);
  }
  ch.added_vertices = std::move(pending_vertices_);
  ch.moved_vertices = std::move(pending_moved_);
  free_vertices_.insert(free_vertices_.end(), pending_removed_vertices_.begin(), pending_removed_vertices_.end());
  ch.removed_vertices = std::move(pending_removed_vertices_);
  for (VertexId v : pending_touched_) {
    touched_mark_[v.idx()] = 0;
    if (vertex_alive_[v.idx()]) ch.touched_vertices.push_back(v);
  }
  events_.clear();
  pending_vertices_.clear();
  pending_moved_.clear();
  pending_removed_vertices_.clear();
  pending_touched_.clear();
  batch_origin_.clear();
  pending_.any = false;
  if (!ch.empty()) {
    ch.mesh = identity_.id;
    ch.serial = ++changes_taken_;
  }
  return ch;
}

void TetMesh::discard_change() {
  // Dropped, not handed out: no consumer is to expect it.
  if (!take_change().empty()) --changes_taken_;
}

std::uint64_t TetMesh::Identity::next() {
  static std::atomic<std::uint64_t> counter{0};
  return ++counter;
}

CompactMaps TetMesh::compact() {
  std::vector<std::uint32_t> vo, to;
  for (std::uint32_t i = 0; i < rest_.size(); ++i)
    if (vertex_alive_[i]) vo.push_back(i);
  for (std::uint32_t i = 0; i < tet_v_.size(); ++i)
    if (tet_alive_[i]) to.push_back(i);
  return renumber(vo, to);
}

namespace {

// Morton code of p in the box [lo, lo + extent]^3: 21 bits per axis, interleaved.
std::uint64_t morton(const Vec3& p, const Vec3& lo, double extent) {
  auto spread = [](std::uint64_t x) {  // bit k of x to bit 3k
    x &= 0x1fffff;
    x = (x | x << 32) & 0x1f00000000ffffULL;
    x = (x | x << 16) & 0x1f0000ff0000ffULL;
    x = (x | x << 8) & 0x100f00f00f00f00fULL;
    x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
    x = (x | x << 2) & 0x1249249249249249ULL;
    return x;
  };
  std::uint64_t code = 0;
  for (int d = 0; d < 3; ++d) {
    const double u = extent > 0 ? (p[d] - lo[d]) / extent : 0.0;
    const auto q = std::uint64_t(std::clamp(u, 0.0, 1.0) * double((1u << 21) - 1));
    code |= spread(q) << d;
  }
  return code;
}

}  // namespace

CompactMaps TetMesh::compact_spatially() {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::max()), hi = -lo;
  for (std::uint32_t i = 0; i < rest_.size(); ++i)
    if (vertex_alive_[i]) {
      lo = lo.cwiseMin(rest_[i]);
      hi = hi.cwiseMax(rest_[i]);
    }
  const double extent = (hi - lo).maxCoeff();
  // Sorted by (code, old id): ties keep their relative order, so the result is deterministic.
  auto ordered = [&](std::size_t n, const std::vector<std::uint8_t>& alive, auto&& position) {
    std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed;
    for (std::uint32_t i = 0; i < n; ++i)
      if (alive[i]) keyed.emplace_back(morton(position(i), lo, extent), i);
    std::sort(keyed.begin(), keyed.end());
    std::vector<std::uint32_t> order(keyed.size());
    for (std::size_t k = 0; k < keyed.size(); ++k) order[k] = keyed[k].second;
    return order;
  };
  const auto vo = ordered(rest_.size(), vertex_alive_, [&](std::uint32_t i) { return rest_[i]; });
  const auto to = ordered(tet_v_.size(), tet_alive_, [&](std::uint32_t i) {
    const auto& v = tet_v_[i];
    return Vec3(0.25 * (rest_[v[0].idx()] + rest_[v[1].idx()] + rest_[v[2].idx()] + rest_[v[3].idx()]));
  });
  return renumber(vo, to);
}

CompactMaps TetMesh::renumber(const std::vector<std::uint32_t>& vertex_order, const std::vector<std::uint32_t>& tet_order) {
  discard_change();
  CompactMaps maps;
  maps.vertex.assign(rest_.size(), VertexId());
  maps.tet.assign(tet_v_.size(), TetId());
  const std::uint32_t nv = std::uint32_t(vertex_order.size()), nt = std::uint32_t(tet_order.size());
  for (std::uint32_t j = 0; j < nv; ++j) maps.vertex[vertex_order[j]] = VertexId(j);
  for (std::uint32_t j = 0; j < nt; ++j) maps.tet[tet_order[j]] = TetId(j);
  std::vector<Vec3> rest(nv);
  std::vector<std::vector<TetId>> vertex_tets(nv);
  for (std::uint32_t j = 0; j < nv; ++j) {
    const std::uint32_t i = vertex_order[j];
    rest[j] = rest_[i];
    vertex_tets[j] = std::move(vertex_tets_[i]);
    for (TetId& t : vertex_tets[j]) t = maps.tet[t.idx()];
  }
  std::vector<std::array<VertexId, 4>> tet_v(nt);
  std::vector<std::array<TetId, 4>> tet_n(nt);
  std::vector<std::array<std::uint16_t, 4>> face_tag(nt);
  std::vector<int> label(nt);
  for (std::uint32_t j = 0; j < nt; ++j) {
    const std::uint32_t i = tet_order[j];
    for (int k = 0; k < 4; ++k) {
      tet_v[j][k] = maps.vertex[tet_v_[i][k].idx()];
      tet_n[j][k] = tet_n_[i][k].is_valid() ? maps.tet[tet_n_[i][k].idx()] : TetId();
    }
    face_tag[j] = face_tag_[i];
    label[j] = label_[i];
  }
  rest_ = std::move(rest);
  vertex_tets_ = std::move(vertex_tets);
  vertex_alive_.assign(nv, 1);
  touched_mark_.assign(nv, 0);
  tet_v_ = std::move(tet_v);
  tet_n_ = std::move(tet_n);
  face_tag_ = std::move(face_tag);
  label_ = std::move(label);
  tet_alive_.assign(nt, 1);
  free_vertices_.clear();
  free_tets_.clear();
  return maps;
}

void TetMesh::validate(const ValidateOptions& opt) const {
  auto fail = [](const std::string& msg) { throw InvalidMesh("validate: " + msg); };
  std::size_t live_v = 0, live_t = 0;
  for (std::uint32_t i = 0; i < rest_.size(); ++i) {
    if (!vertex_alive_[i]) {
      if (!vertex_tets_[i].empty()) fail(vid(VertexId(i)) + " is dead but has incident tets");
      continue;
    }
    ++live_v;
    if (!rest_[i].allFinite()) fail(vid(VertexId(i)) + " has a non-finite position");
    const auto& inc = vertex_tets_[i];
    for (std::size_t k = 0; k < inc.size(); ++k) {
      TetId t = inc[k];
      if (!is_alive(t)) fail(vid(VertexId(i)) + " lists dead " + tid(t));
      if (local_index(t, VertexId(i)) < 0) fail(vid(VertexId(i)) + " lists " + tid(t) + " which does not use it");
      for (std::size_t m = 0; m < k; ++m)
        if (inc[m] == t) fail(vid(VertexId(i)) + " lists " + tid(t) + " twice");
    }
  }
  if (live_v != vertex_alive_count_) fail("live vertex count mismatch");
  for (VertexId v : free_vertices_)
    if (vertex_alive_[v.idx()]) fail("free list holds live " + vid(v));
  for (TetId t : free_tets_)
    if (tet_alive_[t.idx()]) fail("free list holds live " + tid(t));

  for (std::uint32_t i = 0; i < tet_v_.size(); ++i) {
    if (!tet_alive_[i]) continue;
    ++live_t;
    TetId t(i);
    const auto& v = tet_v_[i];
    for (int a = 0; a < 4; ++a) {
      if (!is_alive(v[a])) fail(tid(t) + " uses dead " + vid(v[a]));
      for (int b = 0; b < a; ++b)
        if (v[a] == v[b]) fail(tid(t) + " repeats " + vid(v[a]));
      const auto& inc = vertex_tets_[v[a].idx()];
      if (std::find(inc.begin(), inc.end(), t) == inc.end())
        fail(vid(v[a]) + " does not list " + tid(t) + " among its incident tets");
    }
    if (opt.check_orientation) {
      double vol = volume(t);
      if (!(vol > 0)) {
        std::ostringstream os;
        os << tid(t) << " is not positively oriented (volume " << vol << ")";
        fail(os.str());
      }
    }
    for (int f = 0; f < 4; ++f) {
      auto fv = face_vertices(t, f);
      TetId u = tet_n_[i][f];
      if (u.is_valid()) {
        if (!is_alive(u)) fail(tid(t) + " face " + std::to_string(f) + " points to dead " + tid(u));
        int g = -1;
        for (int k = 0; k < 4; ++k)
          if (tet_n_[u.idx()][k] == t) g = k;
        if (g < 0) fail(tid(t) + " -> " + tid(u) + " is not symmetric");
        auto gv = face_vertices(u, g);
        // Same vertex set, opposite orientation: gv must be a cyclic rotation of reversed fv.
        std::array<VertexId, 3> rev{fv[0], fv[2], fv[1]};
        bool ok = false;
        for (int r = 0; r < 3; ++r)
          ok |= (gv[0] == rev[r] && gv[1] == rev[(r + 1) % 3] && gv[2] == rev[(r + 2) % 3]);
        if (!ok) fail(tid(t) + " and " + tid(u) + " do not share face " + std::to_string(f) + " with opposite orientation");
        if (face_tag_[i][f] != kTagNone) fail(tid(t) + " interior face " + std::to_string(f) + " carries a tag");
      } else {
        // A boundary face must not be shared with any other tet.
        for (TetId w : vertex_tets_[fv[0].idx()]) {
          if (w == t) continue;
          if (local_index(w, fv[1]) >= 0 && local_index(w, fv[2]) >= 0)
            fail(tid(t) + " face " + std::to_string(f) + " is shared with " + tid(w) + " but not linked");
        }
      }
    }
  }
  if (live_t != tet_alive_count_) fail("live tet count mismatch");

  if (opt.check_manifold_boundary) {
    // Every boundary edge in exactly two boundary faces, once in each direction, and the
    // boundary faces around each vertex form a single fan (vertex-manifold).
    std::map<std::pair<std::uint32_t, std::uint32_t>, int> directed;
    IdMap<std::vector<std::pair<std::uint32_t, std::uint32_t>>> link;
    for (const BoundaryFace& bf : boundary_faces()) {
      for (int k = 0; k < 3; ++k) {
        std::uint32_t p = bf.vertices[k].idx(), q = bf.vertices[(k + 1) % 3].idx(),
                      r = bf.vertices[(k + 2) % 3].idx();
        if (++directed[{p, q}] > 1)
          fail("boundary edge (" + std::to_string(p) + "," + std::to_string(q) + ") is non-manifold or mis-oriented");
        link[p].push_back({q, r});
      }
    }
    for (const auto& [e, n] : directed)
      if (!directed.count({e.second, e.first}))
        fail("boundary is open at edge (" + std::to_string(e.first) + "," + std::to_string(e.second) + ")");
    for (auto& [v, edges] : link) {
      // Follow q -> r around v; a single cycle must visit all link edges.
      IdMap<std::uint32_t> next;
      for (auto [q, r] : edges) next[q] = r;
      std::uint32_t start = edges.front().first, cur = start;
      std::size_t steps = 0;
      do {
        cur = next[cur];
        ++steps;
      } while (cur != start && steps <= edges.size());
      if (steps != edges.size()) fail("boundary is not manifold at " + vid(VertexId(v)));
    }
  }
}

}  // namespace incise
