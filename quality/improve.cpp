// The improvement drivers: a queue of tets below the targets, worst first; each popped tet
// gets the best improving flip, else smoothing of its vertices. New and changed tets go back
// on the queue. Global mode sweeps the whole mesh again while a sweep made progress; local
// mode works in the seeds' neighbourhood only and never touches O(mesh) data.
#include <algorithm>
#include <chrono>
#include <queue>
#include <unordered_map>
#include <unordered_set>

#include "quality/collapse.h"
#include "quality/flips.h"
#include "quality/insertion.h"
#include "quality/improve.h"
#include "quality/quality_cache.h"
#include "quality/tet_map.h"
#include "quality/metrics.h"
#include "quality/smoothing.h"

namespace incise {

namespace {

using Clock = std::chrono::steady_clock;

// Worst figures of the report, from angle_quality (the measure the pass computes anyway, at
// under half the cost of the full tet_quality: in local mode under a budget of a few ms, the
// region's before/after figures were most of the time).
struct Stats {
  double min_dih = 180, max_dih = 0, min_rr = 1;
  void add(const AngleQuality& q) {
    min_dih = std::min(min_dih, q.min_dihedral);
    max_dih = std::max(max_dih, q.max_dihedral);
    min_rr = std::min(min_rr, q.radius_ratio);
  }
};

template <class Tets>
Stats stats_of(const TetMesh& mesh, const Tets& tets) {
  Stats s;
  for (auto t : tets)
    if (mesh.is_alive(TetId(t))) s.add(angle_quality(mesh, TetId(t), AngleTargets{}));
  return s;
}

class Driver {
public:
  // base_tets: the input's tet count (global) or the region's size (local), for max_growth.
  Driver(TetMesh& mesh, const ImproveOptions& opt, Clock::time_point deadline, bool has_deadline,
         IdSet* region, std::size_t base_tets)
      : mesh_(mesh),
        opt_(opt),
        deadline_(deadline),
        has_deadline_(has_deadline),
        region_(region),
        growth_cap_(static_cast<long>((opt.max_growth - 1) * double(base_tets))) {
    // Strict radius-ratio guard until insertion starts (allow_insertion()).
    scope_.targets = {opt.target_dihedral_deg, opt.target_max_dihedral_deg, 1.0};
    scope_.region = region;
    for (VertexId v : opt.frozen) frozen_.insert(v.idx());
    flip_.max_ring = opt.max_ring;
    flip_.multi_face = opt.multi_face_removal;
    smooth_.move_surface = opt.move_surface;
    smooth_.move_cut = opt.move_cut;
    smooth_.move_interface = opt.move_interface;
    smooth_.slide_curved = opt.slide_curved;
    smooth_.feature_angle_deg = opt.feature_angle_deg;
    smooth_.feature_line_angle_deg = opt.slide_feature_lines ? opt.feature_line_angle_deg : 0;
    smooth_.iterations = opt.smoothing_iterations;
    smooth_.frozen = &frozen_;
    smooth_.curved_slides = &curved_slides_;
    smooth_.max_curved_slides = opt.max_curved_slides;
    if (opt.slide_curved) smooth_.volume = &volume_;
    // Boundary flips that move the surface: where curved slides may (not on cut faces: a cut
    // is made of tet faces exactly where the blade went).
    if (opt.slide_curved && opt.reshape_surface && opt.move_surface) {
      reshape_.deviation = opt.surface_flip_deviation;
      reshape_.volume = &volume_;
      flip_.reshape = &reshape_;
      flip_.reshape_volume = &volume_;
    }
    collapse_.edge_ratio = opt.collapse_edge_ratio;
    collapse_.tolerance = opt.collapse_tolerance;
    collapse_.surface_deviation = opt.collapse_deviation;
    collapse_.restore_volume = opt.collapse_restores_volume;
    collapse_.feature_angle_deg = opt.feature_angle_deg;
    // Boundary vertices that may not slide may not be contracted away either (the boundary's
    // triangulation then stays as it is).
    collapse_.remove_boundary = opt.move_surface && opt.move_cut;
    collapse_.frozen = &frozen_;
    insert_.max_cavity = opt.max_cavity;
    insert_.edge_stars = opt.edge_star_insertion;
    insert_.iterations = 2 * opt.smoothing_iterations;
    insert_.growth_refused = &growth_refused_;
    // The boundary keeps its shape under boundary insertion, but its triangulation changes: only
    // where boundary vertices may move at all.
    if (opt.boundary_insertion && (opt.move_surface || opt.move_cut))
      insert_.boundary_tags = [surface = opt.move_surface, cut = opt.move_cut](std::uint16_t tag) {
        return tag == kTagCut ? cut : surface;
      };
  }

  // Curved slides may move each label's volume by volume_tolerance of `volumes`.
  void limit_volume(const std::unordered_map<int, double>& volumes) {
    for (const auto& [label, v] : volumes) volume_.limit[label] = opt_.volume_tolerance * std::abs(v);
  }

  // One sweep over `tets`; returns whether anything improved. `seen`: also gathers the
  // figures of `tets` as they are queued (the report's "before", at no extra evaluation).
  template <class Tets>
  bool sweep(const Tets& tets, ImproveReport& rep, Stats* seen = nullptr) {
    for (auto t : tets) {
      const AngleQuality q = push(TetId(t));
      if (seen) seen->add(q);
    }
    bool progress = false;
    while (!queue_.empty()) {
      if (out_of_budget()) {
        rep.budget_exhausted = true;
        break;
      }
      const Entry e = queue_.top();
      queue_.pop();
      if (!mesh_.is_alive(e.tet) || version_[e.tet.idx()].version != e.version) continue;
      ++work_;
      if (step(e.tet, rep)) progress = true;
    }
    while (!queue_.empty()) queue_.pop();
    return progress;
  }

  IdSet moved;

  // The report's figures of live tets, from their last push (the same values angle_quality
  // gives now: min/max dihedral and radius ratio do not depend on the targets); a tet never
  // pushed is evaluated.
  template <class Tets>
  Stats current_stats(const Tets& tets) const {
    Stats st;
    for (auto t : tets) {
      if (!mesh_.is_alive(TetId(t))) continue;
      const Known* k = version_.find(std::uint32_t(t));
      st.add(k ? k->quality : angle_quality(mesh_, TetId(t), AngleTargets{}));
    }
    return st;
  }
  // Insertion adds tets, and the growth cap is shared by the whole pass: global mode first
  // lets flips, contraction and smoothing converge, then allows insertion for what is left,
  // and from then on every operation may trade radius ratio down to the floor
  // (ImproveOptions::radius_ratio_floor). Starting from the converged strict pass, an
  // insertion run never ends worse than the default one.
  bool insertion_allowed = true;
  bool growth_refused() const { return growth_refused_; }
  int work() const { return work_; }
  // From now on an operation may raise its tets' largest dihedral angle up to the mesh's
  // largest now (AngleTargets::max_deg_cap): the worst tets' smallest angles rise past what
  // keeping each set's own largest allowed, and the mesh's largest never gets worse. O(mesh).
  void cap_max_dihedral_at_current() {
    double largest = 0;
    for (TetId t : mesh_.tets()) largest = std::max(largest, angle_quality(mesh_, t, scope_.targets).max_dihedral);
    scope_.targets.max_deg_cap = largest;
  }
  void allow_insertion() {
    insertion_allowed = true;
    scope_.targets.radius_ratio_floor = opt_.radius_ratio_floor;
    // What failed under the strict rule may pass under the floor: retry everything (kept marks
    // cost angle: docs/improve.md#behind-the-defaults).
    stuck_.clear();
    flip_stuck_.clear();
    collapse_stuck_.clear();
  }

private:
  struct Entry {
    double q;
    TetId tet;
    std::uint32_t version;
    bool operator<(const Entry& o) const { return q > o.q; }  // worst on top
  };

  bool out_of_budget() const {
    if (opt_.max_work > 0 && work_ >= opt_.max_work) return true;
    return has_deadline_ && Clock::now() >= deadline_;
  }

  AngleQuality push(TetId t) {
    const AngleQuality a =
        opt_.quality_cache ? opt_.quality_cache->get(mesh_, t, scope_.targets) : angle_quality(mesh_, t, scope_.targets);
    Known& k = version_[t.idx()];
    ++k.version;
    k.quality = a;
    if (a.q < 1) queue_.push({a.q, t, k.version});
    return a;
  }

  // Tets `removed` were replaced by `added`: region, growth, queue and retry marks follow.
  void replaced(const std::vector<TetId>& removed, const std::vector<TetId>& added) {
    grown_ += static_cast<long>(added.size()) - static_cast<long>(removed.size());
    if (region_) {
      for (TetId r : removed) region_->erase(r.idx());
      for (TetId a : added) region_->insert(a.idx());
    }
    for (TetId a : added) push(a);
    changed(added);
  }

  // Tets new or changed shape: operations around them may work again. Each vertex once (the
  // tets around a moved vertex share most of theirs; the marks are sets, never iterated, so
  // clearing them once or many times, in any order, leaves the same sets).
  void changed(std::span<const TetId> tets) {
    touched_.clear();
    for (TetId a : tets)
      for (VertexId w : mesh_.tet_vertices(a)) touched_.push_back(w.idx());
    std::sort(touched_.begin(), touched_.end());
    touched_.erase(std::unique(touched_.begin(), touched_.end()), touched_.end());
    for (std::uint32_t w : touched_) {
      stuck_.erase(w);
      for (TetId u : mesh_.incident_tets(VertexId(w))) {
        flip_stuck_.erase(u.idx());
        collapse_stuck_.erase(u.idx());
      }
    }
  }
  std::vector<std::uint32_t> touched_;

  // A tet with a tiny edge: no flip helps (every configuration of that edge's star keeps it)
  // and smoothing moves a vertex by a fraction of that edge; contracting the edge does.
  bool try_collapse(TetId t, ImproveReport& rep) {
    if (!opt_.collapse || collapse_stuck_.count(t.idx())) return false;
    if (auto c = improve_by_collapse(mesh_, t, scope_, collapse_)) {
      ++rep.contractions;
      rep.volume_change += c->volume_change;
      const std::uint32_t gone = c->removed_vertex.idx();
      moved.erase(gone);
      if (c->kept_moved) moved.insert(c->kept.idx());
      stuck_.erase(gone);
      curved_slides_.erase(gone);
      replaced(c->removed, c->rebuilt);
      return true;
    }
    collapse_stuck_.insert(t.idx());
    return false;
  }

  // Shortest edge below a tenth of the longest: contraction first, before the costlier flips.
  bool has_tiny_edge(TetId t) const {
    const auto tv = mesh_.tet_vertices(t);
    double lo = 1e300, hi = 0;
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j) {
        const double l = (mesh_.rest(tv[i]) - mesh_.rest(tv[j])).squaredNorm();
        lo = std::min(lo, l);
        hi = std::max(hi, l);
      }
    return lo < 0.01 * hi;
  }

  bool step(TetId t, ImproveReport& rep) {
    scope_.growth_left = growth_cap_ - grown_;
    if (has_tiny_edge(t) && try_collapse(t, rep)) return true;
    if (opt_.flips && !flip_stuck_.count(t.idx())) {
      FlipOutcome f = improve_by_flip(mesh_, t, scope_, flip_);
      if (f.kind == FlipOutcome::None) flip_stuck_.insert(t.idx());
      if (f.kind != FlipOutcome::None) {
        rep.surface_flips += f.surface_moved;
        switch (f.kind) {
          case FlipOutcome::Flip23: ++rep.flips23; break;
          case FlipOutcome::Flip32: ++rep.flips32; break;
          case FlipOutcome::Flip44: ++rep.flips44; break;
          case FlipOutcome::BoundaryFlip: ++rep.boundary_flips; break;
          case FlipOutcome::MultiFaceRemoval: ++rep.multi_face_removals; break;
          default: ++rep.edge_removals; break;
        }
        replaced(f.removed, f.added);
        return true;
      }
    }
    if (try_collapse(t, rep)) return true;
    bool any = false;
    if (opt_.smoothing) {
      const auto tv = mesh_.tet_vertices(t);
      for (VertexId v : tv) {
        if (stuck_.count(v.idx())) continue;
        const SmoothMove how = smooth_vertex_how(mesh_, v, scope_, smooth_);
        if (how == SmoothMove::None) {
          stuck_.insert(v.idx());  // until a tet around it changes
          continue;
        }
        ++rep.smoothing_moves;
        rep.feature_slides += how == SmoothMove::FeatureLine;
        moved.insert(v.idx());
        any = true;
        const auto inc = mesh_.incident_tets(v);
        const std::vector<TetId> around(inc.begin(), inc.end());
        for (TetId a : around) push(a);
        changed(around);
        stuck_.erase(v.idx());
      }
    }
    // Insertion checks its growth against scope_.growth_left. (Ids freed by this pass's
    // contractions are not reused before the batch ends, so both can mix.)
    if (!any && opt_.insertion && insertion_allowed && mesh_.is_alive(t) && scope_.growth_left <= 0)
      growth_refused_ = true;
    if (!any && opt_.insertion && insertion_allowed && mesh_.is_alive(t) && scope_.growth_left > 0 &&
        (opt_.insertion_below_deg <= 0 ||
         angle_quality(mesh_, t, AngleTargets{}).min_dihedral < opt_.insertion_below_deg)) {
      work_ += std::max(opt_.insertion_work, 1) - 1;  // the tet's step counted one already
      if (auto ins = improve_by_insertion(mesh_, t, scope_, insert_)) {
        ++rep.insertions;
        rep.boundary_insertions += ins->on_boundary;
        replaced(ins->removed, ins->added);
        return true;
      }
    }
    return any;
  }

  TetMesh& mesh_;
  const ImproveOptions& opt_;
  Clock::time_point deadline_;
  bool has_deadline_;
  IdSet* region_;
  ImproveScope scope_;
  FlipOptions flip_;
  SmoothOptions smooth_;
  CollapseOptions collapse_;
  InsertionOptions insert_;
  SurfaceReshape reshape_;
  bool growth_refused_ = false;
  IdSet frozen_;
  IdMap<int> curved_slides_;
  VolumeAllowance volume_;
  // Smoothing (vertices) or flips (tets) failed and nothing around changed since.
  IdSet stuck_, flip_stuck_, collapse_stuck_;
  // Per tet pushed: its queue version and its figures when pushed. Every tet an operation
  // creates or reshapes is pushed again, so a live tet's figures are its current ones.
  struct Known {
    std::uint32_t version = 0;
    AngleQuality quality;
  };
  TetMap<Known> version_;
  std::priority_queue<Entry> queue_;
  int work_ = 0;
  long growth_cap_;  // how many tets the pass may add in all
  long grown_ = 0;  // net tets added by all operations
};

// Each label's volume over `tets` (live ones). A mesh has a few labels: they are summed in a
// short list (the same sums in the same order as a map's), then handed out as a map.
template <class Tets>
std::unordered_map<int, double> label_volumes(const TetMesh& mesh, const Tets& tets) {
  std::vector<std::pair<int, double>> sums;
  for (auto t : tets) {
    if (!mesh.is_alive(TetId(t))) continue;
    const int label = mesh.label(TetId(t));
    auto it = std::find_if(sums.begin(), sums.end(), [&](const auto& s) { return s.first == label; });
    if (it == sums.end()) it = sums.insert(sums.end(), {label, 0.0});
    it->second += mesh.volume(TetId(t));
  }
  return {sums.begin(), sums.end()};
}

// The largest relative change of one label's volume from `before` to `after`.
double largest_change(const std::unordered_map<int, double>& before, const std::unordered_map<int, double>& after) {
  double worst = 0;
  for (const auto& [label, v0] : before) {
    const auto it = after.find(label);
    const double v1 = it == after.end() ? 0 : it->second;
    if (v0 > 0) worst = std::max(worst, std::abs(v1 - v0) / v0);
  }
  return worst;
}

void finish(ImproveReport& rep, const Driver& d, Clock::time_point start) {
  rep.work = d.work();
  rep.moved_vertices.reserve(d.moved.size());
  for (auto v : d.moved) rep.moved_vertices.emplace_back(v);
  std::sort(rep.moved_vertices.begin(), rep.moved_vertices.end());
  rep.seconds = std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

void accumulate(ImproveReport& into, const ImproveReport& next) {
  into.min_dihedral_after = next.min_dihedral_after;
  into.max_dihedral_after = next.max_dihedral_after;
  into.min_radius_ratio_after = next.min_radius_ratio_after;
  into.tets_after = next.tets_after;
  into.flips23 += next.flips23;
  into.flips32 += next.flips32;
  into.flips44 += next.flips44;
  into.edge_removals += next.edge_removals;
  into.multi_face_removals += next.multi_face_removals;
  into.smoothing_moves += next.smoothing_moves;
  into.insertions += next.insertions;
  into.contractions += next.contractions;
  into.boundary_insertions += next.boundary_insertions;
  into.boundary_flips += next.boundary_flips;
  into.surface_flips += next.surface_flips;
  into.feature_slides += next.feature_slides;
  into.volume_change += next.volume_change;
  into.label_volume_change = std::max(into.label_volume_change, next.label_volume_change);
  into.seconds += next.seconds;
  into.work += next.work;
  into.moved_vertices.insert(into.moved_vertices.end(), next.moved_vertices.begin(), next.moved_vertices.end());
  std::sort(into.moved_vertices.begin(), into.moved_vertices.end());
  into.moved_vertices.erase(std::unique(into.moved_vertices.begin(), into.moved_vertices.end()), into.moved_vertices.end());
  into.budget_exhausted = next.budget_exhausted;
  into.growth_capped = into.growth_capped || next.growth_capped;
}

ImproveReport improve(TetMesh& mesh, const ImproveOptions& opt) {
  const auto start = Clock::now();
  ImproveReport rep;
  const std::vector<TetId> all = mesh.tets();
  rep.tets_before = all.size();
  const auto deadline = start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(opt.time_limit_s));
  Driver d(mesh, opt, deadline, opt.time_limit_s > 0, nullptr, all.size());
  const std::unordered_map<int, double> volumes = label_volumes(mesh, all);
  d.limit_volume(volumes);
  // Sweeps until one makes no progress: a tet stuck in one sweep may become improvable once
  // its neighbours changed. The first one's queueing measures "before". With insertion, the
  // sweeps without it come first: inserting at the first worst tets spent the growth cap on
  // tets that flips and smoothing would have fixed (a sliver-laden box ended at 9.9..155.5
  // degrees instead of 19.7..144.2 without insertion).
  Stats before;
  int pass = 0;
  d.insertion_allowed = false;
  for (int round = 0; round < 8 && !rep.budget_exhausted; ++round, ++pass)
    if (!d.sweep(pass == 0 ? all : mesh.tets(), rep, pass == 0 ? &before : nullptr)) break;
  if (opt.insertion) {
    d.allow_insertion();
    d.cap_max_dihedral_at_current();
    for (int round = 0; round < 8 && !rep.budget_exhausted; ++round, ++pass)
      if (!d.sweep(pass == 0 ? all : mesh.tets(), rep, pass == 0 ? &before : nullptr)) break;
  }
  rep.growth_capped = d.growth_refused();
  rep.min_dihedral_before = before.min_dih;
  rep.max_dihedral_before = before.max_dih;
  rep.min_radius_ratio_before = before.min_rr;
  const std::vector<TetId> after_tets = mesh.tets();
  rep.label_volume_change = largest_change(volumes, label_volumes(mesh, after_tets));
  Stats after = stats_of(mesh, after_tets);
  rep.tets_after = after_tets.size();
  rep.min_dihedral_after = after.min_dih;
  rep.max_dihedral_after = after.max_dih;
  rep.min_radius_ratio_after = after.min_rr;
  finish(rep, d, start);
  return rep;
}

ImproveReport improve_local(TetMesh& mesh, std::span<const TetId> seeds, const ImproveOptions& opt) {
  const auto start = Clock::now();
  ImproveReport rep;
  // Region: the live seeds plus opt.rings rings of tets sharing a vertex.
  IdSet region;
  std::vector<TetId> frontier;
  for (TetId t : seeds)
    if (mesh.is_alive(t) && region.insert(t.idx()).second) frontier.push_back(t);
  // Each vertex's tets once: a vertex met again has all of them in the region already, so the
  // region gets the same tets in the same order (its iteration order is the pass's queueing
  // order) for far fewer lookups.
  IdSet ringed;
  for (int r = 0; r < opt.rings; ++r) {
    std::vector<TetId> next;
    for (TetId t : frontier)
      for (VertexId v : mesh.tet_vertices(t))
        if (ringed.insert(v.idx()).second)
          for (TetId u : mesh.incident_tets(v))
            if (region.insert(u.idx()).second) next.push_back(u);
    frontier = std::move(next);
  }
  rep.tets_before = region.size();
  const bool timed = opt.time_budget_ms > 0;
  const auto deadline =
      start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double, std::milli>(opt.time_budget_ms));
  Driver d(mesh, opt, deadline, timed, &region, region.size());
  const std::unordered_map<int, double> volumes = label_volumes(mesh, region);
  d.limit_volume(volumes);
  if (opt.insertion) d.allow_insertion();  // a local pass has no time to converge first
  Stats before;  // measured by the first sweep as it queues the region
  for (int pass = 0; pass < 4 && !rep.budget_exhausted; ++pass) {
    const std::vector<std::uint32_t> ids(region.begin(), region.end());
    if (!d.sweep(ids, rep, pass == 0 ? &before : nullptr)) break;
  }
  rep.growth_capped = d.growth_refused();
  rep.min_dihedral_before = before.min_dih;
  rep.max_dihedral_before = before.max_dih;
  rep.min_radius_ratio_before = before.min_rr;
  rep.label_volume_change = largest_change(volumes, label_volumes(mesh, region));
  Stats after = d.current_stats(region);
  rep.tets_after = region.size();
  rep.min_dihedral_after = after.min_dih;
  rep.max_dihedral_after = after.max_dih;
  rep.min_radius_ratio_after = after.min_rr;
  finish(rep, d, start);
  return rep;
}

}  // namespace incise
