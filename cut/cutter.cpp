#include "cut/cutter.h"

#include <algorithm>
#include <unordered_set>

#include "cut/carve.h"
#include "cut/cut_step.h"
#include "cut/fragments.h"
#include "cut/separate.h"
#include "mesh/errors.h"

namespace incise {

using namespace cut_detail;

namespace {
double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

bool finite(const Vec3& x) { return x.allFinite(); }
}  // namespace

Cutter::Cutter(TetMesh& mesh, CutOptions options) : mesh_(&mesh), opt_(std::move(options)) {
  if (!(opt_.snap >= 0) || opt_.snap >= 0.5) throw InvalidArgument("cut: snap must be in [0, 0.5)");
  // Room for the cuts' new vertices and tets: the first steps then do not copy the mesh's
  // arrays (an O(mesh) spike); later growth is geometric, so amortized.
  mesh.reserve(mesh.vertex_capacity() + mesh.vertex_capacity() / 8 + 1024,
               mesh.tet_capacity() + mesh.tet_capacity() / 8 + 4096);
  grid_.build(mesh);
  grid_edits_ = mesh.counters().edits;
}

void Cutter::notify(const TopologyChange& change) {
  if (mesh_->counters().edits == grid_edits_) return;  // nothing new (or already taken)
  grid_.update(*mesh_, change);
  grid_edits_ = mesh_->counters().edits;
}

std::vector<TetId> Cutter::first_contact(const Vec3& lo, const Vec3& hi, const PositionFn& positions,
                                         double max_displacement, bool grid_stale) {
  if (grid_stale || !grid_.built()) grid_.build(*mesh_);
  double grow = 0;
  if (positions) {
    grow = max_displacement;
    if (!(grow >= 0)) {  // unknown: measure it (O(V), still far below a scan of the tets)
      grow = 0;
      for (VertexId v : mesh_->vertices()) grow = std::max(grow, (positions(v) - mesh_->rest(v)).norm());
    }
  }
  // The grid's boxes are exact; the margin covers rounding of the rest boxes.
  const double margin = 1e-9 * ((hi - lo).norm() + grow);
  return grid_.query(*mesh_, lo, hi, grow + margin);
}

void Cutter::start(const BladeSegment& blade) {
  if (!finite(blade.a) || !finite(blade.b)) throw InvalidArgument("cut: blade endpoints must be finite");
  blade_ = blade;
  started_ = true;
  front_.clear();
  front_vertices_.clear();
  has_front_ = false;
}

CutStepReport Cutter::finish() {
  const auto t0 = std::chrono::steady_clock::now();
  CutStepReport rep;
  std::vector<TetId> live;
  for (TetId t : front_)
    if (mesh_->is_alive(t)) live.push_back(t);
  started_ = false;
  front_.clear();
  front_vertices_.clear();
  has_front_ = false;
  if (opt_.mode != CutMode::Subdivide || !opt_.improve || live.empty()) return rep;
  if (mesh_->has_pending_change())
    throw InvalidArgument("cut: the mesh has edits not yet taken (call take_change() before finishing a cut)");
  const bool grid_stale = mesh_->counters().edits != grid_edits_;
  ImproveOptions io = opt_.improve_options;
  io.frozen = opt_.frozen;
  io.time_budget_ms = opt_.improve_budget_ms;
  rep.improve = improve_local(*mesh_, live, io);
  rep.ms_improve = ms_since(t0);
  rep.change = mesh_->take_change();
  if (!grid_stale) {
    grid_.update(*mesh_, rep.change);
    grid_edits_ = mesh_->counters().edits;
  }
  rep.tets_added = rep.change.added_tets.size();
  rep.vertices_added = rep.change.added_vertices.size();
  rep.ms = ms_since(t0);
  return rep;
}

CutStepReport Cutter::advance(const BladeSegment& blade, const PositionFn& positions, double max_displacement) {
  if (!started_) {
    start(blade);
    return {};
  }
  if (!finite(blade.a) || !finite(blade.b)) throw InvalidArgument("cut: blade endpoints must be finite");
  const auto tris = swept_triangles(blade_, blade);
  blade_ = blade;
  return run(tris, positions, max_displacement, true);
}

CutStepReport Cutter::cut_plane(const Vec3& point, const Vec3& normal, const PositionFn& positions,
                                double max_displacement) {
  if (!finite(point) || !finite(normal)) throw InvalidArgument("cut: plane point and normal must be finite");
  // The plane's extent: the mesh's box (a one-off O(mesh) cut by nature: it crosses everything).
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (VertexId v : mesh_->vertices()) {
    const Vec3 x = positions ? positions(v) : mesh_->rest(v);
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  if (mesh_->num_vertices() == 0) return {};
  const auto tris = plane_triangles(point, normal, lo, hi);
  return run(tris, positions, max_displacement, false);
}

CutStepReport Cutter::cut_surface(std::span<const CutTriangle> triangles, const PositionFn& positions,
                                  double max_displacement) {
  std::vector<CutTriangle> tris;
  for (const CutTriangle& t : triangles) {
    for (const Vec3& x : t.p)
      if (!finite(x)) throw InvalidArgument("cut: surface vertices must be finite");
    if (t.area() > 0) tris.push_back(t);
  }
  return run(tris, positions, max_displacement, false);
}

CutStepReport Cutter::run(std::span<const CutTriangle> triangles, const PositionFn& positions,
                          double max_displacement, bool use_front) {
  const auto t0 = std::chrono::steady_clock::now();
  CutStepReport rep;
  if (triangles.empty()) return rep;
  if (mesh_->has_pending_change())
    throw InvalidArgument("cut: the mesh has edits not yet taken (call take_change() before cutting)");
  std::vector<Piece> pieces = make_pieces(triangles);
  // The previous step's front is where this step's cut continues, not a rim.
  if (use_front && has_front_) mark_inner_segment(pieces, front_segment_.a, front_segment_.b);
  // Edits since the grid was last in sync that nobody passed to notify(): rebuild on use.
  bool grid_stale = mesh_->counters().edits != grid_edits_;
  // First contact (no front yet, or the walk found nothing): the grid, near the pieces.
  auto scan = [&]() {
    Vec3 lo = pieces[0].lo, hi = pieces[0].hi;
    for (const Piece& p : pieces) {
      lo = lo.cwiseMin(p.lo);
      hi = hi.cwiseMax(p.hi);
    }
    std::vector<TetId> hits = first_contact(lo, hi, positions, max_displacement, grid_stale);
    grid_stale = false;
    return hits;
  };
  std::vector<TetId> seeds = use_front ? front_ : std::vector<TetId>{};

  if (opt_.mode == CutMode::Remove) {
    CarveResult c = carve(*mesh_, pieces, seeds, scan, positions);
    rep.tets_cut = c.removed;
    rep.cut_faces = c.faces_exposed;
    rep.cut_area = c.area;
    front_ = std::move(c.neighbours);
    rep.fragments = find_fragments(*mesh_, front_, opt_.fragment_search_limit);
  } else {
    CutStep step(*mesh_, positions, opt_.snap);
    if (use_front && has_front_) step.add_known_segment(front_segment_.a, front_segment_.b, front_vertices_);
    for (const Piece& p : pieces) {
      step.collect(p, seeds, scan);
      step.embed_boundary(p);
      step.split_crossings(p);
      auto live = step.live_candidates();
      seeds = std::move(live);
    }
    const std::vector<CutFacePair> faces = step.cut_faces(pieces);
    const SeparationResult sep = separate(*mesh_, faces);
    rep.tets_cut = step.tets_cut();
    rep.vertices_duplicated = sep.vertices_duplicated;
    rep.cut_faces = sep.faces_opened;
    rep.cut_area = sep.area;
    front_ = step.live_candidates();
    front_vertices_ = step.segment_vertices(blade_.a, blade_.b);
    front_segment_ = blade_;
    has_front_ = use_front;
    rep.fragments = find_fragments(*mesh_, sep.opened_tets, opt_.fragment_search_limit);
    if (opt_.improve && !front_.empty()) {
      const auto ti = std::chrono::steady_clock::now();
      ImproveOptions io = opt_.improve_options;
      // Only the front must stay exactly where it is (the next step continues from that
      // line). The rest of the cut surface is boundary the pass treats like any other: cut
      // faces stay in their plane, rims (straight creases) slide along their line.
      std::vector<VertexId> frozen = opt_.frozen;
      frozen.insert(frozen.end(), front_vertices_.begin(), front_vertices_.end());
      io.frozen = frozen;
      io.time_budget_ms = opt_.improve_budget_ms;
      rep.improve = improve_local(*mesh_, front_, io);
      rep.ms_improve = ms_since(ti);
      // Flips replace tets: keep the live ones and the improved region as the next walk's start.
      std::vector<TetId> live;
      for (TetId t : front_)
        if (mesh_->is_alive(t)) live.push_back(t);
      front_ = std::move(live);
    }
  }
  rep.change = mesh_->take_change();
  if (!grid_stale) {  // else the next first contact rebuilds it
    grid_.update(*mesh_, rep.change);
    grid_edits_ = mesh_->counters().edits;
  }
  rep.tets_added = rep.change.added_tets.size();
  rep.vertices_added = rep.change.added_vertices.size();
  if (opt_.mode == CutMode::Subdivide) {
    // Tets the improvement created are near the blade too.
    std::unordered_set<std::uint32_t> in(front_.size());
    for (TetId t : front_) in.insert(t.idx());
    for (TetId t : rep.change.added_tets)
      if (mesh_->is_alive(t) && in.insert(t.idx()).second) front_.push_back(t);
  }
  rep.ms = ms_since(t0);
  return rep;
}

}  // namespace incise
