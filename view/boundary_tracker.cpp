#include "view/boundary_tracker.h"

#include <algorithm>

#include "view/wire_format.h"

namespace incise::view {

namespace {
std::uint64_t face_key(TetId t, int local) { return std::uint64_t(t.idx()) * 4 + std::uint64_t(local); }
}  // namespace

BoundaryTracker::BoundaryTracker(const TetMesh& mesh, std::function<bool(VertexId)> fixed,
                                 std::function<bool(VertexId)> loaded)
    : mesh_(mesh), fixed_(std::move(fixed)), loaded_(std::move(loaded)) {
  for (const BoundaryFace& f : mesh.boundary_faces()) look_at(f.tet);
}

std::uint32_t BoundaryTracker::vertex_slot(VertexId v) {
  auto [it, fresh] = vertex_slot_.try_emplace(v.idx(), kNoSlot);
  if (fresh) {
    if (!free_vert_.empty()) {
      it->second = free_vert_.back();
      free_vert_.pop_back();
      vert_[it->second] = v;
    } else {
      it->second = std::uint32_t(vert_.size());
      vert_.push_back(v);
      vert_refs_.push_back(0);
    }
  }
  ++vert_refs_[it->second];
  return it->second;
}

void BoundaryTracker::release_vertex(std::uint32_t slot) {
  if (--vert_refs_[slot] > 0) return;
  vertex_slot_.erase(vert_[slot].idx());
  vert_[slot] = VertexId();
  free_vert_.push_back(slot);
}

void BoundaryTracker::drop(std::uint64_t key) {
  auto it = face_slot_.find(key);
  if (it == face_slot_.end()) return;
  Triangle& t = tri_[it->second];
  for (std::uint32_t s : t.v) release_vertex(s);
  if (t.flags & kTriangleCut) --cut_count_;
  --tri_count_;
  t = Triangle{};
  free_tri_.push_back(it->second);
  face_slot_.erase(it);
}

void BoundaryTracker::look_at(TetId t) {
  for (int f = 0; f < 4; ++f) {
    const std::uint64_t key = face_key(t, f);
    const bool boundary = mesh_.is_alive(t) && !mesh_.neighbor(t, f).is_valid();
    auto it = face_slot_.find(key);
    if (!boundary) {
      if (it != face_slot_.end()) drop(key);
      continue;
    }
    const std::array<VertexId, 3> fv = mesh_.face_vertices(t, f);
    std::uint32_t flags = mesh_.face_tag(t, f) == kTagCut ? kTriangleCut : 0;
    if (fixed_ && fixed_(fv[0]) && fixed_(fv[1]) && fixed_(fv[2])) flags |= kTriangleFixed;
    if (loaded_ && loaded_(fv[0]) && loaded_(fv[1]) && loaded_(fv[2])) flags |= kTriangleLoaded;
    if (it != face_slot_.end()) {
      const Triangle& old = tri_[it->second];
      bool same = old.flags == flags;
      for (int i = 0; i < 3 && same; ++i) same = vert_[old.v[i]] == fv[i];
      if (same) continue;
      drop(key);
    }
    std::uint32_t slot;
    if (!free_tri_.empty()) {
      slot = free_tri_.back();
      free_tri_.pop_back();
    } else {
      slot = std::uint32_t(tri_.size());
      tri_.emplace_back();
    }
    Triangle& tr = tri_[slot];
    for (int i = 0; i < 3; ++i) tr.v[i] = vertex_slot(fv[i]);
    tr.flags = flags;
    tr.tet = t;
    tr.local = f;
    face_slot_.emplace(key, slot);
    ++tri_count_;
    if (flags & kTriangleCut) ++cut_count_;
  }
}

void BoundaryTracker::apply(const TopologyChange& change) {
  for (TetId t : change.removed_tets)
    for (int f = 0; f < 4; ++f) drop(face_key(t, f));
  std::vector<TetId> again(change.added_tets.begin(), change.added_tets.end());
  for (VertexId v : change.touched_vertices)
    if (mesh_.is_alive(v))
      for (TetId t : mesh_.incident_tets(v)) again.push_back(t);
  std::sort(again.begin(), again.end(), [](TetId a, TetId b) { return a.idx() < b.idx(); });
  again.erase(std::unique(again.begin(), again.end()), again.end());
  for (TetId t : again) look_at(t);
}

}  // namespace incise::view
