#pragma once
// The mesh's boundary triangles and vertices in stable slots, as the page holds them: a slot
// keeps its number while its face lives, and freed slots are reused, so the page's arrays stay
// as small as the boundary. Built once from the whole mesh (O(mesh)); each TopologyChange then
// updates it locally: the removed tets' faces go, and the faces of the added tets and of the
// tets around the change's touched vertices are looked at again (a cut opens faces of tets it
// did not re-create, and those sit at touched vertices).
#include <array>
#include <cstdint>
#include <functional>
#include <unordered_map>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise::view {

inline constexpr std::uint32_t kNoSlot = 0xffffffffu;

class BoundaryTracker {
public:
  struct Triangle {
    std::array<std::uint32_t, 3> v{kNoSlot, kNoSlot, kNoSlot};  // vertex slots; kNoSlot: free slot
    std::uint32_t flags = 0;                                     // wire_format.h kTriangle*
    TetId tet;
    int local = 0;
  };

  // `fixed(v)`: whether the scene holds v (drawn as a fixed region); `loaded(v)`: whether a
  // scene load acts on v (drawn as a loaded region). Either may be empty.
  BoundaryTracker(const TetMesh& mesh, std::function<bool(VertexId)> fixed,
                  std::function<bool(VertexId)> loaded = {});
  void apply(const TopologyChange& change);

  const std::vector<Triangle>& triangles() const { return tri_; }       // by slot
  const std::vector<VertexId>& vertices() const { return vert_; }       // by slot; invalid: free
  std::size_t triangle_count() const { return tri_count_; }
  std::size_t cut_triangle_count() const { return cut_count_; }

private:
  void look_at(TetId t);  // brings t's four faces up to date
  void drop(std::uint64_t key);
  std::uint32_t vertex_slot(VertexId v);
  void release_vertex(std::uint32_t slot);

  const TetMesh& mesh_;
  std::function<bool(VertexId)> fixed_, loaded_;
  std::vector<Triangle> tri_;
  std::vector<std::uint32_t> free_tri_;
  std::unordered_map<std::uint64_t, std::uint32_t> face_slot_;  // tet * 4 + local -> triangle slot
  std::vector<VertexId> vert_;
  std::vector<std::uint32_t> vert_refs_;
  std::vector<std::uint32_t> free_vert_;
  std::unordered_map<std::uint32_t, std::uint32_t> vertex_slot_;  // VertexId -> slot
  std::size_t tri_count_ = 0, cut_count_ = 0;
};

}  // namespace incise::view
