#pragma once
// Typed 32-bit handles. A handle is an index into the mesh's per-element arrays;
// ids of live elements never change until TetMesh::compact().
#include <cstdint>
#include <functional>
#include <limits>

namespace incise {

template <class Tag>
class Handle {
public:
  static constexpr std::uint32_t invalid_index = std::numeric_limits<std::uint32_t>::max();

  constexpr Handle() = default;
  constexpr explicit Handle(std::uint32_t i) : idx_(i) {}

  constexpr std::uint32_t idx() const { return idx_; }
  constexpr bool is_valid() const { return idx_ != invalid_index; }

  friend constexpr bool operator==(Handle a, Handle b) { return a.idx_ == b.idx_; }
  friend constexpr bool operator!=(Handle a, Handle b) { return a.idx_ != b.idx_; }
  friend constexpr bool operator<(Handle a, Handle b) { return a.idx_ < b.idx_; }

private:
  std::uint32_t idx_ = invalid_index;
};

struct VertexTag {};
struct TetTag {};
using VertexId = Handle<VertexTag>;
using TetId = Handle<TetTag>;

} // namespace incise

template <class Tag>
struct std::hash<incise::Handle<Tag>> {
  std::size_t operator()(incise::Handle<Tag> h) const noexcept { return std::hash<std::uint32_t>{}(h.idx()); }
};
