#pragma once
// Detached parts after a cut, found locally: flood fills through face neighbours from the
// tets next to the new cut faces, stopped after `limit` tets. A fill that closes before the
// limit has found a whole connected part; when every fill closes (a small body cut through),
// the largest part is the body and the rest are fragments. Cost O(limit) per step at most.
#include <span>
#include <vector>

#include "cut/cutter.h"

namespace incise::cut_detail {

std::vector<Fragment> find_fragments(const TetMesh& mesh, std::span<const TetId> starts, std::size_t limit);

}  // namespace incise::cut_detail
