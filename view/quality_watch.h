#pragma once
// The overlay's mesh-quality figures, kept incrementally: every live tet's smallest dihedral
// angle (rest shape) in an ordered multiset, updated from each TopologyChange (removed tets
// out, added tets in: O(change log mesh)). Built once, O(mesh). The rest shape is what cuts
// and their local improvement change; the deformation's effect on angles is not followed here
// (it would need every tet every frame).
#include <set>
#include <utility>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise::view {

class QualityWatch {
public:
  explicit QualityWatch(const TetMesh& mesh, double below_deg = 10.0);
  void apply(const TopologyChange& change);
  double min_dihedral() const { return angles_.empty() ? 0.0 : angles_.begin()->first; }  // degrees
  std::size_t below() const { return below_; }  // tets with a smallest dihedral under below_deg
  double below_deg() const { return below_deg_; }
  // The tets whose smallest dihedral is under `deg`, worst first, at most `cap` of them
  // (O(answer log mesh)).
  std::vector<TetId> tets_below(double deg, std::size_t cap) const;

private:
  void add(TetId t);
  const TetMesh& mesh_;
  double below_deg_;
  std::vector<double> angle_;  // per tet slot; negative: not counted
  std::set<std::pair<double, std::uint32_t>> angles_;  // (angle, tet id)
  std::size_t below_ = 0;
};

}  // namespace incise::view
