#include "cut/cutter.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <unordered_set>

#include "cut/carve.h"
#include "cut/cutter_impl.h"
#include "cut/cut_step.h"
#include "cut/fragments.h"
#include "cut/separate.h"
#include "cut/specks.h"
#include "cut/sheet.h"
#include "mesh/clock.h"
#include "mesh/errors.h"
#include "quality/metrics.h"

namespace incise {

using namespace cut_detail;

namespace {
bool finite(const Vec3& x) { return x.allFinite(); }

void add_separation(CutStepReport& rep, const SeparationResult& sep) {
  rep.vertices_duplicated += sep.vertices_duplicated;
  rep.cut_faces += sep.faces_opened;
  rep.cut_area += sep.area;
  rep.exposed_area += 2 * sep.area;
}
}  // namespace

void Cutter::Impl::keep_made(Progress& pr) const {
  const std::vector<TetId> added = mesh_->pending_added_tets();
  pr.made.insert(pr.made.end(), added.begin(), added.end());
  // Smoothing reshapes tets without making new ones.
  for (const VertexOrigin& o : mesh_->pending_moved_vertices())
    if (mesh_->is_alive(o.vertex))
      for (TetId t : mesh_->incident_tets(o.vertex)) pr.made.push_back(t);
  // Dead ids go once the list has doubled since it was last compacted: O(1) a tet, amortized.
  if (pr.made.size() > 2 * pr.made_compacted + 64) {
    std::erase_if(pr.made, [&](TetId t) { return !mesh_->is_alive(t); });
    std::sort(pr.made.begin(), pr.made.end(), [](TetId a, TetId b) { return a.idx() < b.idx(); });
    pr.made.erase(std::unique(pr.made.begin(), pr.made.end()), pr.made.end());
    pr.made_compacted = pr.made.size();
  }
}

bool Cutter::Impl::needs_improving(TetId t) const {
  const auto& tv = mesh_->tet_vertices(t);
  const Vec3 &p0 = mesh_->rest(tv[0]), &p1 = mesh_->rest(tv[1]), &p2 = mesh_->rest(tv[2]), &p3 = mesh_->rest(tv[3]);
  // Most tets are clearly inside both bounds: their dihedral cosines say so without the six
  // arc tangents of tet_quality (this runs on every tet near the blade at every step). Only a
  // cosine within 1e-9 of a bound's, or a flat tet, takes the exact figures, so the answer is
  // tet_quality's.
  {
    static const double kCosMin = std::cos(kQueueMinDihedral * 3.14159265358979323846 / 180),
                        kCosMax = std::cos(kQueueMaxDihedral * 3.14159265358979323846 / 180);
    constexpr double kMargin = 1e-9;
    const Vec3 e[6] = {p1 - p0, p2 - p0, p3 - p0, p2 - p1, p3 - p1, p3 - p2};
    const Vec3 n[4] = {e[3].cross(e[4]), e[2].cross(e[1]), e[0].cross(e[2]), e[1].cross(e[0])};
    const double det = e[0].dot(e[1].cross(e[2]));
    static constexpr int kEdgeFaces[6][2] = {{2, 3}, {1, 3}, {1, 2}, {0, 3}, {0, 2}, {0, 1}};
    double len[4];
    bool clear = det > 0 && std::isfinite(det);
    for (int f = 0; f < 4 && clear; ++f) clear = (len[f] = n[f].norm()) > 0 && std::isfinite(len[f]);
    bool bad = false;
    for (int k = 0; k < 6 && clear; ++k) {
      const double c = -n[kEdgeFaces[k][0]].dot(n[kEdgeFaces[k][1]]) / (len[kEdgeFaces[k][0]] * len[kEdgeFaces[k][1]]);
      if (!std::isfinite(c) || std::abs(c - kCosMin) <= kMargin || std::abs(c - kCosMax) <= kMargin) clear = false;
      else bad = bad || c > kCosMin || c < kCosMax;
    }
    if (clear) return bad;
  }
  const TetQuality q = tet_quality(p0, p1, p2, p3);
  return q.min_dihedral < kQueueMinDihedral || q.max_dihedral > kQueueMaxDihedral;
}


Cutter::Impl::Impl(TetMesh& mesh, CutOptions options)
    : mesh_(&mesh), opt_(std::move(options)), progress_(std::make_unique<Progress>()),
      fragment_scratch_(std::make_unique<FragmentScratch>()) {
  if (const std::string e = snap_error(opt_.snap); !e.empty()) throw InvalidArgument("cut: snap: " + e);
  if (opt_.exact_volumes) {
    // Contractions that move the surface, a cut or an interface give their label the volume
    // back by moving the kept vertex; curved slides stay off.
    opt_.improve_options.collapse_restores_volume = true;
    opt_.improve_options.slide_curved = false;
  }
  // Room for the cuts' new vertices and tets: the first steps then do not copy the mesh's
  // arrays (an O(mesh) spike); later growth is geometric, so amortized.
  mesh.reserve(mesh.vertex_capacity() + mesh.vertex_capacity() / 8 + 1024,
               mesh.tet_capacity() + mesh.tet_capacity() / 8 + 4096);
  grid_.build(mesh);
  grid_edits_ = mesh.counters().edits;
}

Cutter::Cutter(TetMesh& mesh, CutOptions options) : impl_(std::make_unique<Impl>(mesh, std::move(options))) {}
Cutter::~Cutter() = default;
Cutter::Cutter(Cutter&&) noexcept = default;
Cutter& Cutter::operator=(Cutter&&) noexcept = default;

void Cutter::start(const BladeSegment& blade) { impl_->start(blade); }
CutStepReport Cutter::advance(const BladeSegment& blade, const PositionFn& positions, double max_displacement) {
  return impl_->advance(blade, positions, max_displacement);
}
bool Cutter::in_cut() const { return impl_->started_; }
CutStepReport Cutter::cut_plane(const Vec3& point, const Vec3& normal, const PositionFn& positions,
                                double max_displacement) {
  return impl_->cut_plane(point, normal, positions, max_displacement);
}
CutStepReport Cutter::cut_surface(std::span<const CutTriangle> triangles, const PositionFn& positions,
                                  double max_displacement) {
  return impl_->cut_surface(triangles, positions, max_displacement);
}
CutStepReport Cutter::finish(const PositionFn& positions) { return impl_->finish(positions); }
bool Cutter::finishing() const { return impl_->finish_left_ > 0; }
CutStepReport Cutter::finish_more() { return impl_->finish_more(); }
void Cutter::notify(const TopologyChange& change) { impl_->notify(change); }
const CutOptions& Cutter::options() const { return impl_->opt_; }
CutOptions& Cutter::options() { return impl_->opt_; }
const BladeSegment& Cutter::blade() const { return impl_->blade_; }
const std::vector<TetId>& Cutter::front_tets() const { return impl_->front_; }
std::size_t Cutter::waiting_tets() const { return impl_->waiting_tets(); }

std::size_t Cutter::Impl::waiting_tets() const {
  std::size_t n = 0;
  for (TetId t : progress_->waiting) n += mesh_->is_alive(t);
  return n;
}

Cutter::PositionFn Cutter::Impl::with_fresh(const PositionFn& positions) {
  fresh_.clear();
  if (!positions) return {};
  // The caller's positions know the vertices of the mesh it has seen; the ones this call
  // makes (split points, duplicates) are known here until the caller applies the change.
  return [this, positions](VertexId v) {
    auto it = fresh_.find(v.idx());
    return it != fresh_.end() ? it->second : positions(v);
  };
}

void Cutter::Impl::remember_fresh(const CutStep& step, const SeparationResult& sep, const PositionFn& positions) {
  if (!positions) return;
  for (const auto& [v, x] : step.created_positions()) fresh_[v] = x;
  for (const SeparationResult::Split& s : sep.splits) fresh_[s.mid.idx()] = 0.5 * (positions(s.a) + positions(s.b));
  for (const auto& [v, copy] : sep.duplicates) fresh_[copy.idx()] = positions(v);
}

SeparationResult Cutter::Impl::open_faces(const CutStep& step, std::span<const CutFacePair> listed, CutStepReport& rep,
                                    const PositionFn& positions, bool split_chords) {
  std::vector<CutFacePair> faces(listed.begin(), listed.end());
  if (progress_->previous) keep_specks_attached(*mesh_, faces, progress_->previous->crease);
  SeparationResult sep = separate(*mesh_, faces, split_chords);
  remember_fresh(step, sep, positions);
  if (progress_->previous) {  // a copy of a vertex is where the vertex is, for that sheet too
    auto& prev = *progress_->previous;
    for (const auto& [v, copy] : sep.duplicates) {
      auto it = prev.sides.find(v.idx());
      if (it != prev.sides.end()) prev.sides[copy.idx()] = it->second;
      if (std::find(prev.crease.begin(), prev.crease.end(), v) != prev.crease.end()) prev.crease.push_back(copy);
    }
  }
  add_separation(rep, sep);
  rep.tets_cut += step.tets_cut();
  fragment_starts_.insert(fragment_starts_.end(), sep.opened_tets.begin(), sep.opened_tets.end());
  return sep;
}

void Cutter::Impl::find_detached(CutStepReport& rep) { find_detached(rep, rep.change.added_tets); }

void Cutter::Impl::find_detached(CutStepReport& rep, std::span<const TetId> added) {
  if (fragment_starts_.empty()) return;
  std::vector<TetId> starts;
  for (TetId t : fragment_starts_)
    if (mesh_->is_alive(t)) starts.push_back(t);
  for (TetId t : added)
    if (mesh_->is_alive(t)) starts.push_back(t);
  fragment_starts_.clear();
  rep.fragments = find_fragments(*mesh_, starts, opt_.fragment_search_limit, *fragment_scratch_, &rep.body);
}

void Cutter::Impl::keep_shut_faces(std::span<const CutFacePair> shut) {
  for (const CutFacePair& f : shut) {
    if (!mesh_->is_alive(f.a.tet)) continue;
    auto fv = mesh_->face_vertices(f.a.tet, f.a.local);
    std::sort(fv.begin(), fv.end(), [](VertexId x, VertexId y) { return x.idx() < y.idx(); });
    shut_faces_.push_back({fv[0], fv[1], fv[2]});
  }
}

void Cutter::Impl::revive_shut(std::vector<CutFacePair>& faces) {
  std::vector<std::array<VertexId, 3>> keys = std::move(shut_faces_);
  shut_faces_.clear();
  std::sort(keys.begin(), keys.end(), [](const auto& x, const auto& y) {
    return std::make_tuple(x[0].idx(), x[1].idx(), x[2].idx()) < std::make_tuple(y[0].idx(), y[1].idx(), y[2].idx());
  });
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  auto same = [](std::array<VertexId, 3> a, const std::array<VertexId, 3>& b) {
    std::sort(a.begin(), a.end(), [](VertexId x, VertexId y) { return x.idx() < y.idx(); });
    return a == b;
  };
  for (const auto& k : keys) {
    if (!mesh_->is_alive(k[0])) continue;
    // The interior face with these corners, if the edits since left it (else it is gone or open).
    for (TetId t : mesh_->incident_tets(k[0])) {
      int f = -1;
      for (int j = 0; j < 4 && f < 0; ++j)
        if (same(mesh_->face_vertices(t, j), k)) f = j;
      if (f < 0) continue;
      const TetId n = mesh_->neighbor(t, f);
      if (!n.is_valid()) break;
      for (int g = 0; g < 4; ++g)
        if (mesh_->neighbor(n, g) == t) {
          bool listed = false;
          for (const CutFacePair& c : faces)
            listed = listed || (c.a.tet == t && c.a.local == f) || (c.b.tet == t && c.b.local == f);
          if (!listed) faces.push_back({{t, f}, {n, g}});
        }
      break;
    }
  }
}

void Cutter::Impl::set_front(const CutStep& step, const BladeSegment& front) {
  front_ = step.live_candidates();
  front_vertices_ = step.segment_vertices(front.a, front.b);
  front_segment_ = front;
  has_front_ = true;
}

void Cutter::Impl::take_record(CutStepReport& rep, bool grid_stale) {
  rep.change = mesh_->take_change();
  if (!grid_stale) {
    grid_.update(*mesh_, rep.change);
    grid_edits_ = mesh_->counters().edits;
  }
  rep.tets_added = rep.change.added_tets.size();
  rep.vertices_added = rep.change.added_vertices.size();
}

void Cutter::Impl::notify(const TopologyChange& change) {
  if (mesh_->counters().edits == grid_edits_) return;  // nothing new (or already taken)
  grid_.update(*mesh_, change);
  grid_edits_ = mesh_->counters().edits;
}

std::vector<TetId> Cutter::Impl::first_contact(const Vec3& lo, const Vec3& hi, const PositionFn& positions,
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

std::vector<TetId> Cutter::Impl::quad_contact(const Piece& local, const PositionFn& positions, double max_displacement) {
  // Boxes of a few grid cells along the quad (a blade across the body has a box as large as
  // the body, a thin quad does not): the cost follows the quad's area, like the cut's.
  std::vector<TetId> out;
  const double cell = grid_.cell_size(), grow = positions ? max_displacement : 0.0;
  std::vector<CutTriangle> todo(local.triangles.begin(), local.triangles.end());
  while (!todo.empty()) {
    const CutTriangle t = todo.back();
    todo.pop_back();
    const Vec3 lo = t.p[0].cwiseMin(t.p[1]).cwiseMin(t.p[2]), hi = t.p[0].cwiseMax(t.p[1]).cwiseMax(t.p[2]);
    if ((hi - lo).maxCoeff() > 4 * cell) {  // split at the longest edge's midpoint
      int e = 0;
      for (int i = 1; i < 3; ++i)
        if ((t.p[(i + 1) % 3] - t.p[i]).squaredNorm() > (t.p[(e + 1) % 3] - t.p[e]).squaredNorm()) e = i;
      const Vec3 m = 0.5 * (t.p[e] + t.p[(e + 1) % 3]);
      todo.push_back({{t.p[e], m, t.p[(e + 2) % 3]}});
      todo.push_back({{m, t.p[(e + 1) % 3], t.p[(e + 2) % 3]}});
      continue;
    }
    const double margin = 1e-9 * ((hi - lo).norm() + grow);
    for (TetId x : grid_.query(*mesh_, lo, hi, grow + margin)) out.push_back(x);
  }
  return out;
}

void Cutter::Impl::start(const BladeSegment& blade) {
  if (!finite(blade.a) || !finite(blade.b)) throw InvalidArgument("cut: blade endpoints must be finite");
  if (!((blade.b - blade.a).norm() > 0)) throw InvalidArgument("cut: the blade's two ends are the same point");
  finish_seeds_.clear();  // a new cut: the last one's remaining improvement is dropped
  repair_seeds_.clear();
  finish_left_ = 0;
  progress_->last_blade = blade_;
  blade_ = blade;
  started_ = true;
  const bool unfinished = progress_->sheet.has_value() || progress_->resume.has_value();
  if (!unfinished) {
    front_.clear();
    *progress_ = Progress{};
    shut_faces_.clear();
    map_.reset();
  }
  rest_known_ = false;  // the new blade is mapped at its first step
  progress_->complete_first = unfinished;
  front_vertices_.clear();
  has_front_ = false;
}

void Cutter::Impl::resume_to_blade(const PositionFn& positions, const BladeSegment& blade) {
  Progress& pr = *progress_;
  if (!pr.resume) return;
  const BladeSegment back = *pr.resume;
  pr.resume.reset();
  if (swept_triangles(back, blade).empty()) return;
  // The blade stopped (or is withdrawn) less than an edge past the last sheet's front: what it
  // swept since is one more sheet, cut with the rest.
  start_sheet(back, blade, positions);
  refresh_waiting(positions, front_);
}

void Cutter::Impl::complete_previous(CutStepReport& rep, const PositionFn& positions) {
  if (!progress_->complete_first) return;
  resume_to_blade(positions, progress_->last_blade);
  finish_sheet(rep, positions);
  *progress_ = Progress{};
  shut_faces_.clear();
  front_.clear();
  front_vertices_.clear();
  has_front_ = false;
}

void Cutter::Impl::improve_after(CutStepReport& rep, std::vector<TetId> seeds, std::vector<VertexId> frozen) {
  if (!opt_.improve || seeds.empty()) return;
  const auto ti = std::chrono::steady_clock::now();
  ImproveOptions io = opt_.improve_options;
  frozen.insert(frozen.end(), opt_.frozen.begin(), opt_.frozen.end());
  io.frozen = frozen;
  io.time_budget_ms = opt_.improve_budget_ms;
  io.quality_cache = &step_quality_;
  rep.improve = improve_local(*mesh_, seeds, io);
  rep.ms_improve += ms_since(ti);
}

void Cutter::Impl::add_crease_faces(const CutStep& step, std::vector<CutFacePair>& faces) const {
  const Progress& pr = *progress_;
  if (!pr.previous || !pr.back_known || pr.previous->crease.empty()) return;  // no crease in the body
  std::vector<TetId> around;  // the tets at the crease, cut by either sheet or by none
  IdSet at_crease;
  for (VertexId v : step.on_segment(pr.previous->crease, pr.back.a, pr.back.b))
    for (TetId t : mesh_->incident_tets(v))
      if (at_crease.insert(t.idx()).second) around.push_back(t);
  IdSet listed;
  for (const CutFacePair& f : faces) listed.insert(4 * f.a.tet.idx() + std::uint32_t(f.a.local));
  for (const CutFacePair& f : step.crease_faces({pr.previous->piece, pr.previous->sides},
                                                {pr.sheet->piece(), pr.memory.side}, pr.back.a, pr.back.b, around))
    if (!listed.count(4 * f.a.tet.idx() + std::uint32_t(f.a.local)) &&
        !listed.count(4 * f.b.tet.idx() + std::uint32_t(f.b.local)))
      faces.push_back(f);
}

void Cutter::Impl::keep_shut(std::vector<TetId>& tets) const {
  const CutMemory& mem = progress_->memory;
  auto on_sheet = [&](VertexId v) {
    auto it = mem.side.find(v.idx());
    return it != mem.side.end() && it->second == 0;
  };
  std::vector<TetId> out;
  IdSet seen;
  for (TetId t : tets) {
    if (!mesh_->is_alive(t) || seen.count(t.idx())) continue;
    for (int f = 0; f < 4; ++f) {
      const TetId n = mesh_->neighbor(t, f);
      if (!n.is_valid()) continue;
      const auto fv = mesh_->face_vertices(t, f);
      if (!(on_sheet(fv[0]) && on_sheet(fv[1]) && on_sheet(fv[2]))) continue;
      for (TetId x : {t, n})
        if (seen.insert(x.idx()).second) out.push_back(x);
    }
  }
  tets = std::move(out);
}

void Cutter::Impl::refresh_waiting(const PositionFn& positions, std::span<const TetId> more, bool recheck) {
  Progress& pr = *progress_;
  std::vector<TetId> all = std::move(pr.waiting);
  const std::size_t kept = recheck ? 0 : all.size();
  all.insert(all.end(), more.begin(), more.end());
  pr.waiting.clear();
  if (!pr.sheet) return;
  const Piece& sp = pr.sheet->piece();
  const double tol = 1e-9 * (sp.hi - sp.lo).norm();
  auto pos = [&](VertexId v) { return positions ? positions(v) : mesh_->rest(v); };
  IdSet seen;
  // An id on the list that `more` holds too is another tet now (ids are reused).
  IdSet fresh;
  if (kept > 0)
    for (TetId t : more) fresh.insert(t.idx());
  for (std::size_t i = 0; i < all.size(); ++i) {
    const TetId t = all[i];
    if (!mesh_->is_alive(t) || !seen.insert(t.idx()).second) continue;
    if (i < kept && !fresh.count(t.idx())) {
      pr.waiting.push_back(t);
      continue;
    }
    bool plus = false, minus = false;
    int off = -1, on = 0;  // the one vertex off the plane, and how many are on it
    std::array<Vec3, 4> x;
    for (std::size_t j = 0; j < 4; ++j) {
      const VertexId v = mesh_->tet_vertices(t)[j];
      x[j] = pos(v);
      auto it = pr.memory.side.find(v.idx());
      const int s = it != pr.memory.side.end() ? it->second : sp.side(x[j]);
      plus |= s > 0;
      minus |= s < 0;
      if (s == 0) ++on;
      else off = int(j);
    }
    // A tet with an interior face in the plane waits too: a blade sweeping along a layer of
    // mesh faces crosses no tet, and its faces open only where the sheet's finish cuts them.
    const bool face_on = !(plus && minus) && on == 3 && mesh_->neighbor(t, off).is_valid();
    if (!(plus && minus) && !face_on) continue;
    for (const CutTriangle& tri : sp.triangles)
      if (tet_may_touch_triangle(x, tri, tol)) {
        pr.waiting.push_back(t);
        break;
      }
  }
}

void Cutter::Impl::open_stale(CutStepReport& rep, const PositionFn& positions) {
  if (shut_faces_.empty()) return;
  CutStep step(*mesh_, positions, opt_.snap);
  std::vector<CutFacePair> faces;
  revive_shut(faces);
  if (faces.empty()) return;
  keep_shut_faces(open_faces(step, faces, rep, positions).shut);
  if (mesh_->has_pending_change()) progress_->edited = true;
}

void Cutter::Impl::cut_provisional(CutStepReport& rep, const PositionFn& positions) {
  Progress& pr = *progress_;
  if (!opt_.provisional || !pr.sheet) return;
  std::vector<TetId> waiting, closed;
  for (TetId t : pr.waiting)
    if (mesh_->is_alive(t)) waiting.push_back(t);
  for (TetId t : pr.closed)
    if (mesh_->is_alive(t)) closed.push_back(t);
  if (waiting.empty() && closed.empty()) return;  // the opening is at the blade already
  const Piece sp = pr.sheet->piece();
  const BladeSegment front = pr.sheet->front();
  // What finish_sheet() would cut if the blade were withdrawn here, on a copy of the sheet's
  // decisions (the provisional ones are dropped with the pieces) and without moving a vertex
  // (a move could not be taken back).
  CutMemory memory = pr.memory;
  mesh_->begin_undo_log();
  struct EndLog {  // the log ends however this returns
    TetMesh* mesh;
    std::optional<TetMesh::UndoLog> log;
    ~EndLog() {
      if (!log) mesh->end_undo_log();
    }
  } end{mesh_, std::nullopt};
  CutStep step(*mesh_, positions, opt_.snap, &memory, false);
  step.set_fixed(opt_.frozen);
  step.set_no_moves();
  if (pr.back_known) step.add_known_segment(pr.back.a, pr.back.b, pr.back_vertices);
  step.add_candidates(closed);
  waiting.insert(waiting.end(), front_.begin(), front_.end());
  std::erase_if(waiting, [&](TetId t) { return !mesh_->is_alive(t); });
  step.collect(sp, waiting, {});
  step.embed_boundary(sp);
  step.split_crossings(sp);
  const SeparationResult sep = separate(*mesh_, step.cut_faces(std::span<const Piece>(&sp, 1)), false);
  remember_fresh(step, sep, positions);
  rep.provisional_faces += sep.faces_opened;
  end.log = mesh_->end_undo_log();
  if (end.log->empty()) return;
  provisional_ = ProvisionalCut{std::move(*end.log), front, step.segment_vertices(front.a, front.b),
                                step.live_candidates()};
}

void Cutter::Impl::take_back_provisional(CutStepReport& rep) {
  if (!provisional_) return;
  ProvisionalCut prov = std::move(*provisional_);
  provisional_.reset();
  Progress& pr = *progress_;
  if (!mesh_->can_undo(prov.log)) {
    // The pieces were edited elsewhere since (a caller's improvement, a part removed): they
    // stay, as if the blade had been withdrawn there, and the next step starts a new sheet
    // from that front.
    pr.sheet.reset();
    pr.waiting.clear();
    pr.closed.clear();
    pr.memory = CutMemory{};
    front_.clear();
    for (TetId t : prov.tets)
      if (mesh_->is_alive(t)) front_.push_back(t);
    front_vertices_.clear();
    for (VertexId v : prov.front_vertices)
      if (mesh_->is_alive(v)) front_vertices_.push_back(v);
    front_segment_ = prov.front;
    has_front_ = true;
    return;
  }
  const bool grid_synced = grid_edits_ == mesh_->counters().edits;
  const auto ids = mesh_->undo(prov.log);
  for (VertexId v : prov.log.vertices) rep.vertices_taken_back += !mesh_->is_alive(v);
  rep.tets_taken_back = ids.size();
  // The undo's edits go into this call's record, and the grid takes them from it.
  if (grid_synced) grid_edits_ = mesh_->counters().edits;
  IdMap<TetId> renamed;
  std::vector<TetId> restored;
  for (const auto& [old_id, new_id] : ids) {
    renamed[old_id.idx()] = new_id;
    restored.push_back(new_id);
  }
  auto rename = [&](TetId t) {
    auto it = renamed.find(t.idx());
    return it != renamed.end() ? it->second : t;
  };
  // Ids the pieces had are dead or (reused) restored tets: lists keep what they held before.
  for (std::vector<TetId>* list : {&pr.waiting, &pr.closed, &pr.made, &front_}) {
    for (TetId& t : *list) t = rename(t);
    std::erase_if(*list, [&](TetId t) { return !mesh_->is_alive(t); });
  }
  for (auto& e : pr.improve_queue) e.first = rename(e.first);
  std::erase_if(pr.improve_queue, [&](const auto& e) { return !mesh_->is_alive(e.first); });
}

CutStepReport Cutter::Impl::advance(const BladeSegment& blade, const PositionFn& caller_positions, double max_displacement) {
  // A blade that was never placed (or was withdrawn) has no "from": refuse rather than guess
  // (this once started a cut silently, and a script missing its start() cut nothing).
  if (!started_)
    throw InvalidArgument("cut: advance() needs a blade: call start(a, b) first (finish() ends a cut; start() "
                          "begins the next)");
  const PositionFn positions = with_fresh(caller_positions);
  if (!finite(blade.a) || !finite(blade.b)) throw InvalidArgument("cut: blade endpoints must be finite");
  const BladeSegment from = blade_;
  blade_ = blade;
  if (opt_.mode == CutMode::Subdivide) {
    // Moving tissue: the blade is mapped into the rest shape through the local deformation
    // around it, and the cut is made there, so the sheet and its front move with the tissue
    // (docs/cut.md#moving-tissue). Still tissue (positions at rest) needs no map.
    BladeSegment rest_from = rest_known_ ? rest_blade_ : from, rest_to = blade;
    std::optional<LocalDeformation> fit;
    if (positions && opt_.material_frame) fit = local_deformation(from, blade, positions, max_displacement);
    if (fit) {
      if (!map_) rest_from = fit->to_rest(from);  // the first step in moving tissue: both ends in this frame
      map_ = fit;
    }
    if (map_) rest_to = map_->to_rest(blade);  // (outside the body: the last map)
    rest_blade_ = rest_to;
    rest_known_ = true;
    if (map_) return sweep(rest_from, rest_to, {}, 0.0);
    return sweep(rest_from, rest_to, positions, max_displacement);
  }
  const auto tris = swept_triangles(from, blade);
  return run(tris, positions, max_displacement, true);
}

std::optional<cut_detail::LocalDeformation> Cutter::Impl::local_deformation(const BladeSegment& from, const BladeSegment& to,
                                                          const PositionFn& positions, double max_displacement) {
  // The tets the blade is in and has not cut yet: whole tissue (the faces behind the blade open
  // as it deforms, and a fit across the gap would follow the opening, not the tissue).
  std::vector<TetId> support;
  for (TetId t : progress_->waiting)
    if (mesh_->is_alive(t)) support.push_back(t);
  if (support.empty())
    for (TetId t : front_)
      if (mesh_->is_alive(t)) support.push_back(t);
  if (support.empty()) {
    // First contact: the tets whose current box meets the box the blade swept.
    Vec3 lo = from.a.cwiseMin(from.b).cwiseMin(to.a).cwiseMin(to.b);
    Vec3 hi = from.a.cwiseMax(from.b).cwiseMax(to.a).cwiseMax(to.b);
    const bool stale = mesh_->counters().edits != grid_edits_;
    for (TetId t : first_contact(lo, hi, positions, max_displacement, stale)) {
      Vec3 tlo = Vec3::Constant(1e300), thi = Vec3::Constant(-1e300);
      for (VertexId v : mesh_->tet_vertices(t)) {
        tlo = tlo.cwiseMin(positions(v));
        thi = thi.cwiseMax(positions(v));
      }
      if ((tlo.array() <= hi.array()).all() && (thi.array() >= lo.array()).all()) support.push_back(t);
    }
    if (stale && !mesh_->has_pending_change()) grid_edits_ = mesh_->counters().edits;  // rebuilt just now
  }
  return fit_local_deformation(*mesh_, support, positions);
}

void Cutter::Impl::start_sheet(const BladeSegment& from, const BladeSegment& to, const PositionFn& positions) {
  Progress& pr = *progress_;
  pr.sheet = Sheet::start(from, to, pr.tol);
  pr.memory = CutMemory{};
  pr.waiting.clear();
  pr.closed.clear();
  pr.back_known = has_front_ && front_segment_.a == from.a && front_segment_.b == from.b;
  pr.back = from;
  pr.back_vertices = pr.back_known ? front_vertices_ : std::vector<VertexId>{};
  if (pr.sheet && pr.back_known) pr.sheet->set_back_is_crease(true);
  // The local edge where this sheet starts sets the next tolerance (the mesh may be graded).
  if (opt_.path_tolerance > 0) {
    const double h = local_edge(positions);
    if (h > 0) {
      pr.tol = opt_.path_tolerance * h;
      pr.reach = h;
    }
  }
}

double Cutter::Impl::local_edge(const PositionFn& positions) const {
  auto pos = [&](VertexId v) { return positions ? positions(v) : mesh_->rest(v); };
  double sum = 0;
  std::size_t n = 0;
  // A sample: the front holds a few hundred tets at most, and the mean of 32 is enough here.
  const std::size_t stride = std::max<std::size_t>(1, front_.size() / 32);
  for (std::size_t i = 0; i < front_.size(); i += stride) {
    if (!mesh_->is_alive(front_[i])) continue;
    const auto& tv = mesh_->tet_vertices(front_[i]);
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b, ++n) sum += (pos(tv[a]) - pos(tv[b])).norm();
  }
  return n ? sum / double(n) : 0.0;
}

bool Cutter::Impl::in_body(const Vec3& p, const PositionFn& positions, double max_displacement) {
  auto pos = [&](VertexId v) { return positions ? positions(v) : mesh_->rest(v); };
  for (TetId t : first_contact(p, p, positions, max_displacement, false)) {
    const auto& tv = mesh_->tet_vertices(t);
    const Vec3 a = pos(tv[0]), b = pos(tv[1]), c = pos(tv[2]), d = pos(tv[3]);
    const double v = (b - a).cross(c - a).dot(d - a);
    if (!(std::abs(v) > 0)) continue;
    const double w1 = (p - a).cross(c - a).dot(d - a) / v, w2 = (b - a).cross(p - a).dot(d - a) / v,
                 w3 = (b - a).cross(c - a).dot(p - a) / v;
    if (w1 >= 0 && w2 >= 0 && w3 >= 0 && w1 + w2 + w3 <= 1) return true;
  }
  return false;
}

namespace {

// The distance between segments [p0, p1] and [q0, q1] (closest points by clamped parameters).
double segment_distance(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1) {
  const Vec3 d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
  double s = 0, t = 0;
  if (a <= 0 && e <= 0) return r.norm();
  if (a <= 0) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const double c = d1.dot(r);
    if (e <= 0) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const double b = d1.dot(d2), den = a * e - b * b;
      s = den > 0 ? std::clamp((b * f - c * e) / den, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1) {
        t = 1;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return ((p0 + s * d1) - (q0 + t * d2)).norm();
}

}  // namespace

Cutter::Impl::Clearance Cutter::Impl::clearance(const Vec3& a, const Vec3& b, const Vec3& normal, double reach,
                                    const PositionFn& positions, double max_displacement) {
  auto pos = [&](VertexId v) { return positions ? positions(v) : mesh_->rest(v); };
  const double len = (b - a).norm(), exact = 1e-9 * reach, in_plane = 1e-7 * reach, close = kCreaseClearance * reach;
  const int pieces = std::max(1, std::min(256, int(std::ceil(len / (2 * grid_.cell_size())))));
  const Vec3 margin = Vec3::Constant(close);
  Clearance out;
  std::unordered_set<std::uint64_t> near;  // edges closer than `close`, once each
  for (int k = 0; k < pieces; ++k) {
    const Vec3 p = a + (double(k) / pieces) * (b - a), q = a + (double(k + 1) / pieces) * (b - a);
    for (TetId t : first_contact(p.cwiseMin(q) - margin, p.cwiseMax(q) + margin, positions, max_displacement, false)) {
      const auto& tv = mesh_->tet_vertices(t);
      for (int i = 0; i < 4; ++i)
        for (int j = i + 1; j < 4; ++j) {
          const Vec3 u = pos(tv[i]), w = pos(tv[j]);
          // Edges in the sheet's plane are cut along, not across.
          if (std::abs(normal.dot(u - a)) <= in_plane && std::abs(normal.dot(w - a)) <= in_plane) continue;
          const double dist = segment_distance(a, b, u, w);
          if (!(dist > exact)) continue;  // through an edge exactly: no sliver
          out.nearest = std::min(out.nearest, dist);
          if (dist < close) near.insert(std::uint64_t(std::min(tv[i].idx(), tv[j].idx())) << 32 | std::max(tv[i].idx(), tv[j].idx()));
        }
    }
  }
  out.near_edges = near.size();
  return out;
}

// Where a sheet ends inside the body, its front becomes the next sheet's crease, embedded as a
// chain of vertices where it crosses the mesh's faces; those vertices lie on both sheets, so no
// contraction takes a sliver that holds one. Two placements leave such slivers: a front a hair
// inside the surface with the blade about to leave the body (the wedge between the two sheets
// and the surface), and a front a hair from a mesh edge (its crossings that close to the edge).
// The sheet may be grown in its own plane, the way the blade went, by up to kFrontExitReach of
// an edge (the path tolerance lets a sheet stray that far from the blade anyway): to the
// nearest place out of the body when that is within reach; else, when edges pass the front
// closer than kCreaseClearance of an edge, to the place with the fewest such edges (ties: the
// one that clears them most), provided it clears every edge by kCreaseClearanceMin. Else the
// front stays where the blade left it: a move to a place that is no clearer only shuffles
// which tets are slivers, and moves a corner for nothing (docs/cut.md#curved-paths).
void Cutter::Impl::place_front(const BladeSegment& to, const PositionFn& positions, double max_displacement) {
  Progress& pr = *progress_;
  const BladeSegment f = pr.sheet->front();
  const Vec3 n = pr.sheet->normal(), along = f.b - f.a;
  const double len = along.norm();
  if (!(len > 0) || !(pr.reach > 0)) return;
  const Vec3 e = along / len;
  Vec3 d = 0.5 * ((to.a + to.b) - (f.a + f.b));  // the blade's motion, in the plane, across the front
  d -= d.dot(e) * e;
  d -= d.dot(n) * n;
  if (!(d.norm() > 1e-12 * len)) return;
  d *= kFrontExitReach * pr.reach / d.norm();
  constexpr int kPlaces = 8;  // candidate places, d / kPlaces apart
  auto shift = [&](int k) { return (double(k) / kPlaces) * d; };
  auto grow_to = [&](int k) { pr.sheet->extend({f.a + shift(k), f.b + shift(k)}, 0); };
  const int samples = std::min(64, 2 + int(std::ceil(len / (0.5 * pr.reach))));
  auto outside = [&](const Vec3& s) {
    for (int i = 0; i < samples; ++i)
      if (in_body(f.a + (double(i) / (samples - 1)) * along + s, positions, max_displacement)) return false;
    return true;
  };
  if (outside(Vec3::Zero())) return;  // the sheet ended outside the body: no crease in it
  if (outside(d)) {
    int k = 1;
    while (k < kPlaces && !outside(shift(k))) ++k;
    grow_to(k);
    return;
  }
  const Clearance here = clearance(f.a, f.b, n, pr.reach, positions, max_displacement);
  if (here.near_edges == 0) return;
  int best = 0;
  Clearance chosen = here;
  for (int k = 1; k <= kPlaces && chosen.near_edges > 0; ++k) {
    const Clearance c = clearance(f.a + shift(k), f.b + shift(k), n, pr.reach, positions, max_displacement);
    if (c.near_edges < chosen.near_edges || (c.near_edges == chosen.near_edges && c.nearest > chosen.nearest))
      chosen = c, best = k;
  }
  if (best > 0 && chosen.nearest >= kCreaseClearanceMin * pr.reach) grow_to(best);
}

CutStepReport Cutter::Impl::sweep(const BladeSegment& from, const BladeSegment& to, const PositionFn& positions,
                            double max_displacement) {
  const auto t0 = std::chrono::steady_clock::now();
  CutStepReport rep;
  const auto tris = swept_triangles(from, to);
  if (tris.empty()) return rep;
  if (mesh_->has_pending_change())
    throw InvalidArgument("cut: the mesh has edits not yet taken (call take_change() before cutting)");
  take_back_provisional(rep);
  complete_previous(rep, positions);
  Progress& pr = *progress_;
  bool grid_stale = mesh_->counters().edits != grid_edits_;
  // This step's quad: where the walk looks for the tets the blade reached.
  Piece local;
  local.triangles = tris;
  finish_piece(local);
  auto scan = [&]() {
    std::vector<TetId> hits = first_contact(local.lo, local.hi, positions, max_displacement, grid_stale);
    grid_stale = false;
    return hits;
  };
  std::vector<VertexId> frozen;
  std::vector<TetId> seeds;
  if (pr.tol == 0 && opt_.path_tolerance > 0) {
    const double h = local_edge(positions);
    pr.tol = opt_.path_tolerance * h;
    pr.reach = h;
  }
  bool waits = false;  // the blade left the plane and is not yet far enough from the front
  // The turn at `from`: how far this step's end leaves the previous step's straight
  // continuation, across the sheet's plane.
  const std::optional<BladeSegment> before = pr.step_from;
  pr.step_from = from;
  auto corner = [&]() {
    // Not in the material frame: there each step is mapped into the rest shape through the
    // local deformation of its time, and the turns of the mapped path are the tissue's motion,
    // not the hand's (they ended sheets at every other step of the pushed organ's cut).
    if (pr.tol <= 0 || !before || map_) return false;
    const Vec3& n = pr.sheet->normal();
    auto turn = [&](const Vec3& p0, const Vec3& p1, const Vec3& p2) {
      const double last = (p1 - p0).norm();
      if (!(last > 0)) return 0.0;
      return std::abs(n.dot((p2 - p1) - (p1 - p0) * ((p2 - p1).norm() / last)));
    };
    const double t = std::max(turn(before->a, from.a, to.a), turn(before->b, from.b, to.b));
    return t > kCornerShare * pr.tol;
  };
  const bool at_corner = pr.sheet && corner();
  if (!(pr.sheet && !at_corner && pr.sheet->extend(to, pr.tol))) {
    // A new plane (the first step, or the blade turned): the old sheet is cut in full, its
    // front becoming a crease the new sheet starts from.
    if (pr.sheet && pr.tol > 0) {
      if (!grid_stale && grid_.built() && (!positions || (max_displacement >= 0 && max_displacement <= grid_.cell_size())))
        place_front(to, positions, max_displacement);
      pr.resume = pr.sheet->front();
    }
    finish_sheet(rep, positions, true);
    const BladeSegment back = pr.resume ? *pr.resume : from;
    auto far = [&](const BladeSegment& b) {
      return std::max((b.a - to.a).norm(), (b.b - to.b).norm()) >= pr.reach;
    };
    if (pr.resume && !at_corner && !far(*pr.resume)) {
      waits = true;
    } else {
      pr.resume.reset();
      start_sheet(back, to, positions);
      if (!(back.a == from.a && back.b == from.b)) {
        local.triangles = swept_triangles(back, to);
        if (local.triangles.empty()) local.triangles = tris;
        finish_piece(local);
      }
    }
  }
  if (waits) {
    // Nothing is cut while the blade moves away from the last front: finish_sheet() cut what
    // the old sheet swept, and the next sheet sweeps from that front.
    seeds = front_;
    frozen = front_vertices_;
  } else {
    // The walk starts from where the last step was, then goes on from the tets the grid says
    // the step's quad may touch that it did not reach: a quad may reach tets no walk over it
    // from the front's tets reaches (another lobe of the body met mid-sheet, tissue beyond an
    // earlier cut's open faces, or beyond a notch where a sheet starts at a crease). Missed, they
    // would stay whole: the parts joined across a curved path, a cut stopped at an earlier one. Not where the tissue has moved by more than a grid cell (the query would
    // grow to the whole region the tissue came from; the walk alone then).
    std::vector<TetId> contact;
    if (!grid_stale && grid_.built() &&
        (!positions || (max_displacement >= 0 && max_displacement <= grid_.cell_size())))
      contact = quad_contact(local, positions, max_displacement);
    if (!pr.sheet) cut_quad(rep, local, scan, {front_, contact}, positions, to, seeds, frozen);
    else step_sheet(rep, local, scan, {front_, contact}, positions, seeds, frozen);
  }
  if (mesh_->has_pending_change()) pr.edited = true;
  improve_after(rep, seeds, frozen);
  if (pr.sheet && opt_.improve && !seeds.empty() && !rep.improve.budget_exhausted) pr.improve_queue.clear();
  keep_sheet_lists(positions);
  // Parts the committed cut detached are found before the provisional pieces are made (those
  // are taken back: a part they alone cut off is not detached). A step that detached one makes
  // none: the scene may remove the part.
  find_detached(rep, mesh_->pending_added_tets());
  keep_made(pr);
  if (rep.fragments.empty()) cut_provisional(rep, positions);
  take_record(rep, grid_stale);
  rep.ms = ms_since(t0);
  return rep;
}

// A step whose quad is not planar (the blade turned out of its plane within the step): cut in
// full like a one-shot surface, its front embedded for the next step to continue from.
void Cutter::Impl::cut_quad(CutStepReport& rep, const Piece& local, const std::function<std::vector<TetId>()>& scan,
                      const Walk& walk, const PositionFn& positions, const BladeSegment& to, std::vector<TetId>& seeds,
                      std::vector<VertexId>& frozen) {
  Progress& pr = *progress_;
  std::vector<Piece> pieces = make_pieces(local.triangles);
  if (pr.back_known) mark_inner_segment(pieces, pr.back.a, pr.back.b);
  CutStep step(*mesh_, positions, opt_.snap);
  step.set_fixed(opt_.frozen);
  if (pr.back_known) step.add_known_segment(pr.back.a, pr.back.b, pr.back_vertices);
  seeds.assign(walk.from.begin(), walk.from.end());
  for (const Piece& p : pieces) {
    step.collect(p, seeds, scan, walk.then);
    step.embed_boundary(p);
    step.split_crossings(p);
    seeds = step.live_candidates();
  }
  open_faces(step, step.cut_faces(pieces), rep, positions);
  set_front(step, to);
  frozen = front_vertices_;
  if (mesh_->has_pending_change()) seeds = front_;
}

// A step of the current sheet: the tets its quad reached are cut against the sheet, the faces
// that can open open, and the rest wait; `seeds` and `frozen` say what the step's improvement
// works on and must hold.
void Cutter::Impl::step_sheet(CutStepReport& rep, const Piece& local, const std::function<std::vector<TetId>()>& scan,
                        const Walk& walk, const PositionFn& positions, std::vector<TetId>& seeds, std::vector<VertexId>& frozen) {
  Progress& pr = *progress_;
  const Piece& sp = pr.sheet->piece();
  CutStep step(*mesh_, positions, opt_.snap, &pr.memory, true);
  step.set_fixed(opt_.frozen);
  step.add_candidates(waiting_ahead(positions));
  step.add_candidates(pr.closed);
  step.collect(local, walk.from, scan, walk.then);
  step.split_crossings(sp);
  std::vector<CutFacePair> faces = step.cut_faces(std::span<const Piece>(&sp, 1));
  add_crease_faces(step, faces);
  const SeparationResult sep = open_faces(step, faces, rep, positions, false);
  for (const SeparationResult::Split& s : sep.splits) pr.memory.side[s.mid.idx()] = 0;  // on the sheet
  for (const auto& [v, copy] : sep.duplicates) {
    auto it = pr.memory.side.find(v.idx());
    if (it != pr.memory.side.end()) pr.memory.side[copy.idx()] = it->second;
  }
  front_ = step.live_candidates();
  // Closed cut faces wait: those this step left closed, and earlier ones it did not list (a
  // tet beside one may have an apex whose side waits for the blade).
  for (const CutFacePair& f : sep.shut) {
    pr.closed.push_back(f.a.tet);
    pr.closed.push_back(f.b.tet);
  }
  keep_shut(pr.closed);
  refresh_waiting(positions, front_);
  // The improvement works on what was cut; the tets still waiting (and the closed faces)
  // keep their vertices, whose sides are decided or about to be.
  IdSet wait;
  for (const auto* list : {&pr.waiting, &pr.closed})
    for (TetId t : *list) {
      wait.insert(t.idx());
      for (VertexId v : mesh_->tet_vertices(t)) frozen.push_back(v);
    }
  // So does the crease the sheet started from: its vertices are where both sheets meet (on
  // the previous sheet's faces only, until this one is finished, they would slide off it).
  if (pr.back_known)
    for (const auto* list : {&pr.back_vertices, pr.previous ? &pr.previous->crease : nullptr})
      if (list)
        for (VertexId v : step.on_segment(*list, pr.back.a, pr.back.b)) frozen.push_back(v);
  ++pr.step;
  if (mesh_->has_pending_change())
    for (TetId t : front_)
      if (!wait.count(t.idx()) && needs_improving(t)) pr.improve_queue.emplace_back(t, pr.step);
  std::erase_if(pr.improve_queue, [&](const auto& e) {
    return !mesh_->is_alive(e.first) || wait.count(e.first.idx()) || e.second + kImproveSteps < pr.step;
  });
  IdSet in;
  for (const auto& e : pr.improve_queue)
    if (in.insert(e.first.idx()).second) seeds.push_back(e.first);
}

// A sheet that starts at a crease (an earlier sheet's front) waits for many tets beyond that
// edge: they cross its plane's extension behind the crease, in the earlier sheet's tissue, and
// their section touches the polygon along the crease at most. The polygon is convex, so while
// the back edge is one of its edges it lies wholly on one side of that edge's line, and no step
// of the sheet cuts a tet lying on the other side; offering them at every step cost most of a
// step's time on a path that turns often (docs/cut.md#curved-paths). They stay on the waiting
// list: the sheet's finish and the improvement's frozen vertices see them as before.
std::vector<TetId> Cutter::Impl::waiting_ahead(const PositionFn& positions) const {
  const Progress& pr = *progress_;
  if (!pr.back_known || !pr.sheet) return pr.waiting;
  const Piece& sp = pr.sheet->piece();
  const Vec3 along = pr.back.b - pr.back.a;
  Vec3 u = sp.normal.cross(along);
  const double len = along.norm();
  if (!(len > 0) || !(u.norm() > 0)) return pr.waiting;
  u /= u.norm();
  const double tol = 1e-6 * len;
  // Into the polygon: the side of its farthest point; give up when it has points on both.
  double lo = 0, hi = 0;
  for (const CutTriangle& tri : sp.triangles)
    for (const Vec3& p : tri.p) {
      const double d = u.dot(p - pr.back.a);
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
  if (lo < -tol && hi > tol) return pr.waiting;
  if (lo < -tol) u = -u;
  auto pos = [&](VertexId v) { return positions ? positions(v) : mesh_->rest(v); };
  std::vector<TetId> ahead;
  ahead.reserve(pr.waiting.size());
  for (TetId t : pr.waiting) {
    bool behind = true;
    for (VertexId v : mesh_->tet_vertices(t))
      if (u.dot(pos(v) - pr.back.a) > tol) {
        behind = false;
        break;
      }
    if (!behind) ahead.push_back(t);
  }
  return ahead;
}

// After a step's improvement: the sheet's lists and the front follow the step's edits.
void Cutter::Impl::keep_sheet_lists(const PositionFn& positions) {
  Progress& pr = *progress_;
  // The sheet's bookkeeping, on this step's edits so far (the provisional pieces come after it
  // and are taken back before the next step: the sheet's lists keep the tets they came from).
  // Decisions about vertices the improvement moved off the cut surface or removed are void.
  for (VertexId v : mesh_->pending_removed_vertices()) {
    pr.memory.forget(v);
    if (pr.previous) {  // its id may come back as another vertex
      pr.previous->sides.erase(v.idx());
      std::erase(pr.previous->crease, v);
    }
  }
  for (const VertexOrigin& o : mesh_->pending_moved_vertices()) {
    auto it = pr.memory.side.find(o.vertex.idx());
    if (it != pr.memory.side.end() && it->second != 0) pr.memory.forget(o.vertex);
    if (pr.previous) {
      auto p = pr.previous->sides.find(o.vertex.idx());
      if (p != pr.previous->sides.end() && p->second != 0) pr.previous->sides.erase(p);
    }
  }
  if (pr.sheet) {
    // The improvement held the waiting tets' vertices: those it did not replace wait as before.
    const std::vector<TetId> added = mesh_->pending_added_tets();
    refresh_waiting(positions, added, false);
    if (!pr.improve_queue.empty())
      for (TetId t : added)
        if (needs_improving(t)) pr.improve_queue.emplace_back(t, pr.step);
    // A flip of closed cut faces (a 4-4 flip about an edge in the plane) makes new closed faces
    // in the plane: they wait with the others.
    pr.closed.insert(pr.closed.end(), added.begin(), added.end());
    keep_shut(pr.closed);
  }
  {
    IdSet in(front_.size());
    std::vector<TetId> live;
    for (TetId t : front_)
      if (mesh_->is_alive(t) && in.insert(t.idx()).second) live.push_back(t);
    for (TetId t : mesh_->pending_added_tets())
      if (in.insert(t.idx()).second) live.push_back(t);
    front_ = std::move(live);
  }
}

CutStepReport Cutter::Impl::cut_plane(const Vec3& point, const Vec3& normal, const PositionFn& caller_positions,
                                double max_displacement) {
  const PositionFn positions = with_fresh(caller_positions);
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

CutStepReport Cutter::Impl::cut_surface(std::span<const CutTriangle> triangles, const PositionFn& caller_positions,
                                  double max_displacement) {
  const PositionFn positions = with_fresh(caller_positions);
  std::vector<CutTriangle> tris;
  for (const CutTriangle& t : triangles) {
    for (const Vec3& x : t.p)
      if (!finite(x)) throw InvalidArgument("cut: surface vertices must be finite");
    if (t.area() > 0) tris.push_back(t);
  }
  return run(tris, positions, max_displacement, false);
}

CutStepReport Cutter::Impl::run(std::span<const CutTriangle> triangles, const PositionFn& positions,
                          double max_displacement, bool use_front) {
  const auto t0 = std::chrono::steady_clock::now();
  CutStepReport rep;
  if (triangles.empty()) return rep;
  if (mesh_->has_pending_change())
    throw InvalidArgument("cut: the mesh has edits not yet taken (call take_change() before cutting)");
  take_back_provisional(rep);
  complete_previous(rep, positions);
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
  const std::vector<TetId> seeds = use_front ? front_ : std::vector<TetId>{};
  if (opt_.mode == CutMode::Remove) carve_pieces(pieces, seeds, scan, positions, rep);
  else subdivide_pieces(pieces, seeds, scan, positions, use_front, rep);
  take_record(rep, grid_stale);
  find_detached(rep);
  if (opt_.mode == CutMode::Subdivide) {
    // Tets the improvement created are near the blade too.
    IdSet in(front_.size());
    for (TetId t : front_) in.insert(t.idx());
    for (TetId t : rep.change.added_tets)
      if (mesh_->is_alive(t) && in.insert(t.idx()).second) front_.push_back(t);
  }
  rep.ms = ms_since(t0);
  return rep;
}

void Cutter::Impl::carve_pieces(std::span<const Piece> pieces, std::span<const TetId> seeds, const ContactFn& scan,
                          const PositionFn& positions, CutStepReport& rep) {
  CarveResult c = carve(*mesh_, pieces, seeds, scan, positions);
  rep.tets_cut = c.removed;
  rep.cut_faces = c.faces_exposed;
  rep.cut_area = c.area / 2;
  rep.exposed_area = c.area;
  front_ = std::move(c.neighbours);
  fragment_starts_.insert(fragment_starts_.end(), front_.begin(), front_.end());
}

void Cutter::Impl::subdivide_pieces(std::span<const Piece> pieces, std::vector<TetId> seeds, const ContactFn& scan,
                              const PositionFn& positions, bool use_front, CutStepReport& rep) {
  CutStep step(*mesh_, positions, opt_.snap);
  step.set_fixed(opt_.frozen);
  if (use_front && has_front_) step.add_known_segment(front_segment_.a, front_segment_.b, front_vertices_);
  for (const Piece& p : pieces) {
    step.collect(p, seeds, scan);
    step.embed_boundary(p);
    step.split_crossings(p);
    seeds = step.live_candidates();
  }
  const std::vector<CutFacePair> faces = step.cut_faces(pieces);
  const SeparationResult sep = separate(*mesh_, faces);
  rep.tets_cut = step.tets_cut();
  rep.vertices_duplicated = sep.vertices_duplicated;
  rep.cut_faces = sep.faces_opened;
  rep.cut_area = sep.area;
  rep.exposed_area = 2 * sep.area;
  front_ = step.live_candidates();
  front_vertices_ = step.segment_vertices(blade_.a, blade_.b);
  front_segment_ = blade_;
  has_front_ = use_front;
  fragment_starts_.insert(fragment_starts_.end(), sep.opened_tets.begin(), sep.opened_tets.end());
  if (opt_.improve && !front_.empty()) improve_around_front(rep);
}

void Cutter::Impl::improve_around_front(CutStepReport& rep) {
  const auto ti = std::chrono::steady_clock::now();
  ImproveOptions io = opt_.improve_options;
  // Only the front must stay exactly where it is (the next step continues from that line).
  // The rest of the cut surface is boundary the pass treats like any other: cut faces stay in
  // their plane, rims (straight creases) slide along their line.
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

}  // namespace incise
