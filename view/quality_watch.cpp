#include "view/quality_watch.h"

#include "quality/metrics.h"

namespace incise::view {

QualityWatch::QualityWatch(const TetMesh& mesh, double below_deg) : mesh_(mesh), below_deg_(below_deg) {
  for (TetId t : mesh.tets()) add(t);
}

void QualityWatch::add(TetId t) {
  if (angle_.size() <= t.idx()) angle_.resize(mesh_.tet_capacity(), -1.0);
  if (angle_[t.idx()] >= 0) return;
  const double a = tet_quality(mesh_, t).min_dihedral;
  angle_[t.idx()] = a;
  angles_.emplace(a, t.idx());
  if (a < below_deg_) ++below_;
}

std::vector<TetId> QualityWatch::tets_below(double deg, std::size_t cap) const {
  std::vector<TetId> out;
  for (auto it = angles_.begin(); it != angles_.end() && it->first < deg && out.size() < cap; ++it)
    out.push_back(TetId(it->second));
  return out;
}

void QualityWatch::apply(const TopologyChange& change) {
  for (TetId t : change.removed_tets) {
    if (t.idx() >= angle_.size() || angle_[t.idx()] < 0) continue;
    const double a = angle_[t.idx()];
    angles_.erase({a, t.idx()});
    if (a < below_deg_) --below_;
    angle_[t.idx()] = -1.0;
  }
  for (TetId t : change.added_tets)
    if (mesh_.is_alive(t)) add(t);
}

}  // namespace incise::view
