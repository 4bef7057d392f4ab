// Withdrawing the blade: the last sheet finished, then finish()'s improvement (the repair of
// every tet the drag made, then the released front), in one call or in slices (finish_more()).
#include <algorithm>
#include <chrono>

#include "cut/cut_step.h"
#include "cut/cutter.h"
#include "cut/cutter_impl.h"
#include "cut/separate.h"
#include "mesh/clock.h"
#include "mesh/errors.h"
#include "quality/metrics.h"

namespace incise {

using namespace cut_detail;

void Cutter::Impl::finish_sheet(CutStepReport& rep, const PositionFn& positions, bool next_follows) {
  Progress& pr = *progress_;
  if (!pr.sheet) {
    open_stale(rep, positions);
    return;
  }
  const Piece sp = pr.sheet->piece();
  const BladeSegment front = pr.sheet->front();
  refresh_waiting(positions, {});
  std::vector<TetId> closed;
  for (TetId t : pr.closed)
    if (mesh_->is_alive(t)) closed.push_back(t);
  has_front_ = false;
  front_vertices_.clear();
  CutStep step(*mesh_, positions, opt_.snap, &pr.memory, false);
  step.set_fixed(opt_.frozen);
  if (next_follows) step.set_crease_front(front.a, front.b);
  if (pr.back_known) step.add_known_segment(pr.back.a, pr.back.b, pr.back_vertices);
  step.add_candidates(closed);
  std::vector<TetId> seeds = pr.waiting;
  seeds.insert(seeds.end(), front_.begin(), front_.end());
  step.collect(sp, seeds, {});
  // Nothing crosses the sheet: no boundary to embed (a blade grazing a face leaves the mesh as
  // it was). A blade sweeping along a layer of interior faces crosses no tet either, but the
  // faces the blade passed last still wait to open (the walk over the sheet finds them).
  if (pr.waiting.empty() && closed.empty()) {
    refresh_waiting(positions, step.live_candidates());
    if (pr.waiting.empty()) {
      pr.sheet.reset();
      open_stale(rep, positions);
      return;
    }
  }
  step.embed_boundary(sp);
  step.split_crossings(sp);
  std::vector<CutFacePair> faces = step.cut_faces(std::span<const Piece>(&sp, 1));
  add_crease_faces(step, faces);
  revive_shut(faces);
  keep_shut_faces(open_faces(step, faces, rep, positions).shut);
  set_front(step, front);
  pr.sheet.reset();
  pr.waiting.clear();
  pr.closed.clear();
  if (next_follows) pr.previous = Progress::PreviousSheet{sp, std::move(pr.memory.side), front_vertices_};
  else pr.previous.reset();
  pr.memory = CutMemory{};
  if (mesh_->has_pending_change()) pr.edited = true;
}

CutStepReport Cutter::Impl::finish(const PositionFn& caller_positions) {
  const auto t0 = std::chrono::steady_clock::now();
  // A cut made in the rest shape (moving tissue) is finished there.
  const PositionFn positions = with_fresh(map_ ? PositionFn{} : caller_positions);
  CutStepReport rep;
  if (mesh_->has_pending_change())
    throw InvalidArgument("cut: the mesh has edits not yet taken (call take_change() before finishing a cut)");
  const bool grid_stale = mesh_->counters().edits != grid_edits_;
  take_back_provisional(rep);
  std::vector<TetId> live;
  for (const auto& e : progress_->improve_queue) live.push_back(e.first);
  resume_to_blade(positions, blade_);
  finish_sheet(rep, positions);
  keep_made(*progress_);
  std::vector<TetId> bad;
  for (TetId t : progress_->made)
    if (mesh_->is_alive(t) && needs_improving(t)) bad.push_back(t);
  const bool edited = progress_->edited;
  live.insert(live.end(), front_.begin(), front_.end());
  for (std::vector<TetId>* list : {&live, &bad}) {
    std::erase_if(*list, [&](TetId t) { return !mesh_->is_alive(t); });
    std::sort(list->begin(), list->end(), [](TetId a, TetId b) { return a.idx() < b.idx(); });
    list->erase(std::unique(list->begin(), list->end()), list->end());
  }
  started_ = false;
  front_.clear();
  front_vertices_.clear();
  has_front_ = false;
  *progress_ = Progress{};
  shut_faces_.clear();
  map_.reset();
  rest_known_ = false;
  finish_seeds_.clear();
  repair_seeds_.clear();
  finish_left_ = 0;
  if (opt_.mode == CutMode::Subdivide && opt_.improve && edited && !(live.empty() && bad.empty())) {
    // The front need no longer stay where it is: its tets get the improvement with its
    // vertices free (a step's improvement keeps them frozen, and nothing else revisits them).
    // With a slice, the first one now and the rest in finish_more().
    finish_seeds_ = std::move(live);
    repair_seeds_ = std::move(bad);
    repair_seeds_.insert(repair_seeds_.end(), finish_seeds_.begin(), finish_seeds_.end());
    finish_left_ = opt_.finish_improve_work;
    improve_finish_slice(rep, opt_.finish_improve_slice > 0 ? opt_.finish_improve_slice : opt_.finish_improve_work);
  }
  end_finish_record(rep, grid_stale, t0);
  return rep;
}

// finish() and finish_more(): the record taken, the grid kept exact, the figures filled in.
void Cutter::Impl::end_finish_record(CutStepReport& rep, bool grid_stale, std::chrono::steady_clock::time_point t0) {
  take_record(rep, grid_stale);
  find_detached(rep);
  keep_finish_seeds(rep.change);
  rep.ms = ms_since(t0);
}

void Cutter::Impl::improve_finish_slice(CutStepReport& rep, int work) {
  work = std::min(work, finish_left_);
  std::erase_if(finish_seeds_, [&](TetId t) { return !mesh_->is_alive(t); });
  std::erase_if(repair_seeds_, [&](TetId t) { return !mesh_->is_alive(t); });
  if (work <= 0 || (finish_seeds_.empty() && repair_seeds_.empty())) {
    finish_left_ = 0;
    return;
  }
  bool first = true;
  while (work > 0) {
    ImproveOptions io = opt_.improve_options;
    io.frozen = opt_.frozen;
    io.time_budget_ms = opt_.improve_budget_ms;
    io.max_work = work;
    io.insertion = opt_.finish_insertion_below_deg > 0;
    io.insertion_below_deg = opt_.finish_insertion_below_deg;
    // First the repair: only the tets short of the queue's bounds count, so the passes go over
    // them alone and try again what failed while their neighbours were still bad. With the
    // improvement's own targets from the start, one pass over the whole region spent the budget
    // and a stuck sliver stayed (docs/cut.md#curved-paths).
    const bool repair = !repair_seeds_.empty();
    if (repair) {
      io.target_dihedral_deg = std::min(io.target_dihedral_deg, kQueueMinDihedral);
      io.target_max_dihedral_deg = std::max(io.target_max_dihedral_deg, kQueueMaxDihedral);
    }
    const auto ti = std::chrono::steady_clock::now();
    // Later slices seed only the region's tets still short of the targets (with their ring):
    // queueing the whole region again each slice cost more than its operations.
    std::vector<TetId> seeds;
    if (opt_.finish_improve_slice > 0 || repair) {
      for (TetId t : repair ? repair_seeds_ : finish_seeds_) {
        const TetQuality q = tet_quality(*mesh_, t);
        if (q.min_dihedral < io.target_dihedral_deg || q.max_dihedral > io.target_max_dihedral_deg) seeds.push_back(t);
      }
    } else {
      seeds = finish_seeds_;
    }
    const ImproveReport r = improve_local(*mesh_, seeds, io);
    rep.ms_improve += ms_since(ti);
    if (first) rep.improve = r;
    else accumulate(rep.improve, r);
    first = false;
    const int spent = std::max(r.work, 1);
    finish_left_ -= spent;
    work -= spent;
    // Spent: the next slice goes on. Converged: the repair hands the rest of the budget to the
    // improvement's own targets, over the region and what the repair made; those are done.
    if (r.budget_exhausted) break;
    if (!repair) {
      finish_left_ = 0;
      break;
    }
    repair_seeds_.clear();
    for (TetId t : mesh_->pending_added_tets()) finish_seeds_.push_back(t);
  }
  if (finish_left_ <= 0) {
    finish_seeds_.clear();
    repair_seeds_.clear();
  }
}

void Cutter::Impl::keep_finish_seeds(const TopologyChange& change) {
  if (finish_left_ <= 0) return;
  // A slice that changed nothing leaves the next one the same mesh, seeds and options: it
  // would spend its operations on the same failed attempts, frame after frame
  // (docs/cut.md#the-defaults). The improvement is done. Under
  // a time cap (improve_budget_ms) the next slice would stop at about the same attempt: done
  // too, with what fitted.
  if (change.empty()) {
    finish_left_ = 0;
    finish_seeds_.clear();
    repair_seeds_.clear();
    return;
  }
  for (std::vector<TetId>* list : {&finish_seeds_, &repair_seeds_}) {
    if (list->empty() && list == &repair_seeds_) continue;  // the repair is over
    for (TetId t : change.added_tets)
      if (mesh_->is_alive(t)) list->push_back(t);
    std::erase_if(*list, [&](TetId t) { return !mesh_->is_alive(t); });
    std::sort(list->begin(), list->end(), [](TetId a, TetId b) { return a.idx() < b.idx(); });
    list->erase(std::unique(list->begin(), list->end()), list->end());
  }
}

CutStepReport Cutter::Impl::finish_more() {
  CutStepReport rep;
  if (finish_left_ <= 0) return rep;
  if (mesh_->has_pending_change())
    throw InvalidArgument("cut: the mesh has edits not yet taken (call take_change() before finish_more())");
  const auto t0 = std::chrono::steady_clock::now();
  const bool grid_stale = mesh_->counters().edits != grid_edits_;
  improve_finish_slice(rep, opt_.finish_improve_slice > 0 ? opt_.finish_improve_slice : finish_left_);
  end_finish_record(rep, grid_stale, t0);
  return rep;
}

}  // namespace incise
