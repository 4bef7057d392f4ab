#pragma once
// Tets' angle figures kept between local improvement passes over overlapping regions: the
// cutter improves the tets near the blade at every step, and consecutive steps' regions share
// most of their tets, which the pass evaluated again each time. The figures depend on the four
// corner positions (in order) and the targets alone, so an entry stands for whatever tet holds
// its id while those are the same (an id that came back as another tet, or a corner that moved,
// is computed again): a figure taken from it is the one angle_quality() would compute now, bit
// for bit. Work follows the tets asked; memory is bounded (kMaxEntries: past it the cache
// starts afresh, which costs time, never a different figure).
#include <array>
#include <cstdint>

#include "mesh/tet_mesh.h"
#include "quality/dihedral_objective.h"
#include "quality/tet_map.h"

namespace incise {

class AngleQualityCache {
public:
  AngleQuality get(const TetMesh& mesh, TetId t, const AngleTargets& targets) {
    if (!same(targets, targets_)) {
      entries_.clear();
      targets_ = targets;
    }
    const auto& tv = mesh.tet_vertices(t);
    const std::array<Vec3, 4> x = {mesh.rest(tv[0]), mesh.rest(tv[1]), mesh.rest(tv[2]), mesh.rest(tv[3])};
    if (entries_.size() >= kMaxEntries) entries_.clear();
    Entry& e = entries_[t.idx()];
    if (e.valid && e.x == x) return e.quality;
    e.valid = true;
    e.x = x;
    e.quality = angle_quality(x[0], x[1], x[2], x[3], targets);
    return e.quality;
  }

private:
  static bool same(const AngleTargets& a, const AngleTargets& b) {
    return a.min_deg == b.min_deg && a.max_deg == b.max_deg && a.radius_ratio_floor == b.radius_ratio_floor &&
           a.max_deg_cap == b.max_deg_cap;
  }
  struct Entry {
    bool valid = false;
    std::array<Vec3, 4> x{Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
    AngleQuality quality;
  };
  // A cut step's region is a few thousand tets; a drag's steps revisit the last few regions.
  static constexpr std::size_t kMaxEntries = std::size_t(1) << 16;
  TetMap<Entry> entries_;
  AngleTargets targets_;
};

}  // namespace incise
