#pragma once
// What one improvement operation may touch: the targets it measures against and, in local
// mode, the region (tet ids) it must stay inside. Shared by flips, smoothing and the drivers.
#include <cstdint>
#include <unordered_set>

#include "mesh/id_set.h"
#include "quality/dihedral_objective.h"

namespace incise {

struct ImproveScope {
  AngleTargets targets;
  const IdSet* region = nullptr;  // nullptr: the whole mesh
  long growth_left = 1L << 60;  // how many more tets the pass may add (ImproveOptions::max_growth)
  bool contains(TetId t) const { return region == nullptr || region->count(t.idx()) > 0; }
};

}  // namespace incise
