// Coarsening: shortest edges first, each contraction checked for topology (edge_collapse.h),
// surface (features, surface link, deviation) and quality, then the improvement pass.
#include "quality/coarsen.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <queue>
#include <set>
#include <tuple>
#include <unordered_map>
#include <unordered_set>

#include "mesh/edge_collapse.h"
#include "mesh/errors.h"
#include "mesh/point_locator.h"
#include "quality/dihedral_objective.h"
#include "quality/surface_star.h"

namespace incise {

namespace {

std::uint64_t edge_key(VertexId a, VertexId b) {
  std::uint32_t x = a.idx(), y = b.idx();
  if (x > y) std::swap(x, y);
  return (std::uint64_t(x) << 32) | y;
}

// An input surface vertex removed by a contraction, once per sheet it was on: it must stay
// near that sheet.
struct RemovedPoint {
  Vec3 p;
  std::uint64_t sheet;
};

class Coarsener {
public:
  Coarsener(TetMesh& m, const CoarsenOptions& o, double target, double deviation)
      : m_(m), opt_(o), deviation_(deviation), collapse_below_(target),
        longest_(o.max_edge_factor * target) {
    // The improvement pass's default targets: between two valid directions, the one whose
    // tets it would rate better.
    targets_.min_deg = ImproveOptions{}.target_dihedral_deg;
    targets_.max_deg = ImproveOptions{}.target_max_dihedral_deg;
    classify();
  }

  int run() {
    int done = 0;
    for (int pass = 0; pass < opt_.passes; ++pass) {
      const int before = done;
      for (VertexId v : m_.vertices()) push_edges(v, true);
      while (!queue_.empty()) {
        const auto [len, a, b] = queue_.top();
        queue_.pop();
        const VertexId va(a), vb(b);
        if (!m_.is_alive(va) || !m_.is_alive(vb) || !adjacent(va, vb)) continue;
        if (try_edge(va, vb)) ++done;
      }
      if (done == before) break;
    }
    return done;
  }

private:
  enum class Kind : std::uint8_t { Interior, Smooth, Crease, Corner };

  // Surface vertices, feature edges and corners of the input (the surface never gains a vertex,
  // so the classes hold throughout; feature edges follow their contractions).
  void classify() {
    kind_.assign(m_.vertex_capacity(), Kind::Interior);
    owned_.assign(m_.vertex_capacity(), {});
    std::unordered_map<std::uint64_t, EdgeFaceTally> edges;
    const double cos_feature = std::cos(opt_.feature_angle_deg * std::numbers::pi / 180);
    for (TetId t : m_.tets())
      for (int f = 0; f < 4; ++f) {
        if (!is_surface_face(m_, t, f)) continue;
        const TetId u = m_.neighbor(t, f);
        if (u.is_valid() && m_.label(u) < m_.label(t)) continue;  // an interface face once
        const auto fv = m_.face_vertices(t, f);
        const std::uint64_t patch = patch_of(m_, t, f);
        const Vec3 n = patch_normal(m_, t, f);
        for (int i = 0; i < 3; ++i) {
          kind_[fv[i].idx()] = Kind::Smooth;
          edges[edge_key(fv[i], fv[(i + 1) % 3])].add(patch, n);
        }
      }
    std::vector<int> features(m_.vertex_capacity(), 0);
    for (const auto& [key, e] : edges)
      if (e.feature(cos_feature)) {
        feature_.insert(key);
        ++features[key >> 32];
        ++features[key & 0xffffffffu];
      }
    for (std::size_t v = 0; v < features.size(); ++v)
      if (features[v] == 2) kind_[v] = Kind::Crease;
      else if (features[v] > 0) kind_[v] = Kind::Corner;
  }

  bool adjacent(VertexId a, VertexId b) const {
    for (TetId t : m_.incident_tets(a))
      if (m_.local_index(t, b) >= 0) return true;
    return false;
  }

  // The edges at v shorter than the target (only those to higher ids: each edge once when
  // every vertex is pushed).
  void push_edges(VertexId v, bool higher_only = false) {
    std::vector<VertexId> seen;
    for (TetId t : m_.incident_tets(v))
      for (VertexId w : m_.tet_vertices(t)) {
        if (w == v || (higher_only && w.idx() < v.idx()) || std::find(seen.begin(), seen.end(), w) != seen.end()) continue;
        seen.push_back(w);
        const double l = (m_.rest(v) - m_.rest(w)).norm();
        if (l < collapse_below_) queue_.push({l, std::min(v.idx(), w.idx()), std::max(v.idx(), w.idx())});
      }
  }

  // The surface stays a surface (surface_link_ok), and a crease does not fold onto another
  // feature line.
  bool surface_link_ok(VertexId keep, VertexId remove) const {
    if (!incise::surface_link_ok(m_, keep, remove)) return false;
    if (kind_[remove.idx()] == Kind::Crease) {
      if (!feature_.count(edge_key(keep, remove))) return false;  // a crease vertex stays on its line
      for (std::uint32_t w : surface_neighbours(m_, remove))
        if (w != keep.idx() && feature_.count(edge_key(remove, VertexId(w))) && feature_.count(edge_key(keep, VertexId(w))))
          return false;
    }
    return true;
  }

  // Every input surface vertex `v` answers for (and v itself) within the deviation of the
  // surface faces around it after the contraction.
  bool deviation_ok(VertexId v, VertexId keep, VertexId remove) const {
    std::vector<RemovedPoint> pts = owned_[v.idx()];
    if (v == keep) {
      pts.insert(pts.end(), owned_[remove.idx()].begin(), owned_[remove.idx()].end());
      for (std::uint64_t s : surface_sheets(m_, remove)) pts.push_back({m_.rest(remove), s});
    }
    if (pts.empty()) return true;
    const auto faces = surface_faces_after(m_, v, keep, remove);
    for (const RemovedPoint& q : pts) {
      double best = 1e300;
      for (const SurfaceFace& f : faces) {
        if (f.sheet != q.sheet) continue;
        best = std::min(best, (q.p - closest_on_triangle(q.p, m_.rest(f.v[0]), m_.rest(f.v[1]), m_.rest(f.v[2]))).norm());
        if (best <= deviation_) break;
      }
      if (best > deviation_) return false;
    }
    return true;
  }

  struct Candidate {
    CollapsePlan plan;
    double q = -1e300;
  };

  bool evaluate(VertexId keep, VertexId remove, Candidate& out) const {
    const Kind k = kind_[remove.idx()];
    if (k == Kind::Corner) return false;
    const bool surface = k != Kind::Interior;
    if (surface && !surface_link_ok(keep, remove)) return false;
    CollapseCheck c = check_collapse(m_, keep, remove, surface ? 1.0 : 0.0);
    if (!c.ok()) return false;
    for (const auto& tv : c.plan.tets)
      for (VertexId w : tv)
        if (w != keep && (m_.rest(w) - m_.rest(keep)).norm() > longest_) return false;
    AngleQuality before;
    for (TetId t : m_.incident_tets(remove)) before.combine(angle_quality(m_, t, targets_));
    const AngleQuality after = angle_quality(m_, c.plan.tets, targets_);
    if (after.min_dihedral < std::min(opt_.min_dihedral_deg, before.min_dihedral) ||
        after.max_dihedral > std::max(opt_.max_dihedral_deg, before.max_dihedral) ||
        after.radius_ratio < std::min(opt_.radius_ratio_floor, before.radius_ratio))
      return false;
    if (surface) {
      if (!deviation_ok(keep, keep, remove)) return false;
      for (std::uint32_t w : surface_neighbours(m_, remove))
        if (w != keep.idx() && !deviation_ok(VertexId(w), keep, remove)) return false;
    }
    out.plan = std::move(c.plan);
    out.q = after.q;
    return true;
  }

  bool try_edge(VertexId a, VertexId b) {
    Candidate best, c;
    bool found = false;
    for (const auto& [keep, remove] : {std::pair{a, b}, std::pair{b, a}})
      if (evaluate(keep, remove, c) && (!found || c.q > best.q)) {
        best = std::move(c);
        found = true;
      }
    if (!found) return false;
    const VertexId keep = best.plan.keep, remove = best.plan.remove;
    if (kind_[remove.idx()] != Kind::Interior) {
      auto& into = owned_[keep.idx()];
      into.insert(into.end(), owned_[remove.idx()].begin(), owned_[remove.idx()].end());
      for (std::uint64_t s : surface_sheets(m_, remove)) into.push_back({m_.rest(remove), s});
      owned_[remove.idx()].clear();
      owned_[remove.idx()].shrink_to_fit();
      if (kind_[remove.idx()] == Kind::Crease) {  // its other feature edge now ends at `keep`
        feature_.erase(edge_key(keep, remove));
        for (std::uint32_t w : surface_neighbours(m_, remove))
          if (feature_.erase(edge_key(remove, VertexId(w)))) feature_.insert(edge_key(keep, VertexId(w)));
      }
    }
    collapse_edge(m_, best.plan);
    push_edges(keep);
    return true;
  }

  TetMesh& m_;
  const CoarsenOptions& opt_;
  double deviation_, collapse_below_, longest_;
  AngleTargets targets_;
  std::vector<Kind> kind_;
  std::vector<std::vector<RemovedPoint>> owned_;  // input surface vertices contracted into this one
  std::unordered_set<std::uint64_t> feature_;
  using Entry = std::tuple<double, std::uint32_t, std::uint32_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> queue_;
};

}  // namespace

double mean_edge_length(const TetMesh& m) {
  std::unordered_set<std::uint64_t> seen;
  double sum = 0;
  for (TetId t : m.tets()) {
    const auto& v = m.tet_vertices(t);
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j)
        if (seen.insert(edge_key(v[i], v[j])).second) sum += (m.rest(v[i]) - m.rest(v[j])).norm();
  }
  return seen.empty() ? 0 : sum / double(seen.size());
}

CoarsenReport coarsen(TetMesh& mesh, const CoarsenOptions& opt) {
  if (!(opt.edge_factor > 0) || !(opt.max_edge_factor >= 1) || !(opt.max_deviation >= 0) || !(opt.target_edge >= 0))
    throw InvalidArgument("coarsen: edge_factor must be > 0, max_edge_factor >= 1, max_deviation and target_edge >= 0");
  CoarsenReport r;
  r.tets_before = mesh.num_tets();
  r.vertices_before = mesh.num_vertices();
  r.mean_edge_before = mean_edge_length(mesh);
  r.target_edge = opt.target_edge > 0 ? opt.target_edge : opt.edge_factor * r.mean_edge_before;
  r.max_deviation = opt.max_deviation > 0 ? opt.max_deviation : 0.1 * r.target_edge;
  if (mesh.num_tets() == 0) return r;
  Coarsener c(mesh, opt, r.target_edge, r.max_deviation);
  // Contraction refuses what would invert or flatten a tet around the kept vertex; flips and
  // smoothing in between reshape those stars, so later rounds contract more.
  for (int round = 0; round < std::max(1, opt.rounds); ++round) {
    const int done = c.run();
    r.contractions += done;
    if (!opt.improve) break;
    ImproveOptions io;
    io.time_limit_s = 0;  // deterministic: bounded by work, not by the clock
    io.max_work = int(std::min<std::size_t>(50 * mesh.num_tets(), 1u << 30));
    io.max_growth = 1.2;
    const ImproveReport ir = improve(mesh, io);
    if (round == 0) r.improve = ir;
    else accumulate(r.improve, ir);
    if (done == 0) break;
  }
  r.tets_after = mesh.num_tets();
  r.vertices_after = mesh.num_vertices();
  r.mean_edge_after = mean_edge_length(mesh);
  return r;
}

}  // namespace incise
