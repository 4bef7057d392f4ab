#pragma once
// Detached parts after a cut, found locally: flood fills through face neighbours from the
// tets next to the new cut faces, stopped after `limit` tets. A fill that closes before the
// limit has found a whole connected part; when every fill closes (a small body cut through),
// the largest part by volume is the body and the rest are fragments. Cost O(limit) per step at most.
#include <span>
#include <vector>

#include "cut/cutter.h"

namespace incise::cut_detail {

// Which fill reached a tet, by tet id: kept between calls (grown with the mesh, never
// cleared: a stamp per call says which entries are current), so a step's search costs the
// tets it visits and no hashing.
struct FragmentScratch {
  std::vector<std::uint32_t> stamp;
  std::vector<int> owner;
  std::uint32_t now = 0;
};

// `body`, when given, receives the part taken as the body when every fill closed (empty
// otherwise): a scene whose constraints hold a smaller part may find that one free.
std::vector<Fragment> find_fragments(const TetMesh& mesh, std::span<const TetId> starts, std::size_t limit,
                                     FragmentScratch& scratch, Fragment* body = nullptr);

}  // namespace incise::cut_detail
