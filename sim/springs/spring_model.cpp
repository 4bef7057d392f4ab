// SpringModel: building from a mesh, local updates, forces, energies and the stable step.
// The integrators live in spring_integrators.cpp.
#include "sim/springs/spring_model.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "mesh/errors.h"

namespace incise {

SpringCalibration calibrate_springs(const Material& m, const SpringOptions& o) {
  check_material(m, "materials");  // springs have no incompressible limit: 0.5 is refused
  SpringCalibration c;
  if (!o.volume_term) {  // Van Gelder's rule as published: E exact, nu = 1/4
    c.spring_modulus = m.young;
    c.effective_poisson = 0.25;
    return c;
  }
  const double nu = m.poisson;
  // kappa / mu_s: exact (lambda - mu) / mu for nu >= 1/4, floored so the barrier never vanishes.
  const double r = std::max(nu > 0.25 ? (4 * nu - 1) / (1 - 2 * nu) : 0.0, o.min_volume_ratio);
  // With lambda = (1 + r) mu_s: E = mu_s (5 + 3r) / (2 + r), solved for mu_s (= mu when r is exact).
  const double mu_s = m.young * (2 + r) / (5 + 3 * r);
  c.spring_modulus = 2.5 * mu_s;
  c.volume_modulus = r * mu_s;
  c.effective_poisson = (1 + r) / (2 * (2 + r));
  return c;
}

namespace {

// Gradient of the signed volume with respect to each vertex: dV/dx_k.
std::array<Vec3, 4> volume_gradient(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3) {
  const Vec3 e1 = x1 - x0, e2 = x2 - x0, e3 = x3 - x0;
  std::array<Vec3, 4> g;
  g[1] = e2.cross(e3) / 6;
  g[2] = e3.cross(e1) / 6;
  g[3] = e1.cross(e2) / 6;
  g[0] = -(g[1] + g[2] + g[3]);
  return g;
}

double signed_volume(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3) {
  return (x1 - x0).dot((x2 - x0).cross(x3 - x0)) / 6;
}

constexpr const auto& kEdges = kTetEdges;

// The index in kTetEdges of the edge joining corners i and j.
int tet_edge_index(int i, int j) {
  if (i > j) std::swap(i, j);
  return i == 0 ? j - 1 : i + j;  // (0,1)0 (0,2)1 (0,3)2 (1,2)3 (1,3)4 (2,3)5
}

}  // namespace

SpringModel::SpringModel(const TetMesh& mesh, const MaterialTable& materials, const SpringOptions& options)
    : opt_(options), materials_(materials), follower_(mesh) {
  if (!(opt_.damping >= 0) || !std::isfinite(opt_.damping))
    throw InvalidArgument("springs.damping: expected a finite value >= 0 [1/s]");
  if (!(opt_.min_volume_ratio >= 0) || !std::isfinite(opt_.min_volume_ratio))
    throw InvalidArgument("springs.min_volume_ratio: expected a finite value >= 0");
  if (!(opt_.viscosity >= 0) || !std::isfinite(opt_.viscosity))
    throw InvalidArgument("springs.viscosity: expected a finite time constant >= 0 [s]");
  if (!(opt_.stiffening >= 0) || !(opt_.stiffening <= 100))
    throw InvalidArgument("springs.stiffening: expected a value in [0, 100]");
  if (!(opt_.barrier_limit > 0 && opt_.barrier_limit < 1))
    throw InvalidArgument("springs.barrier_limit: expected a value in (0, 1)");
  if (!(opt_.cg_tolerance > 0) || opt_.cg_max_iterations < 1)
    throw InvalidArgument("springs.cg: expected tolerance > 0 and max_iterations >= 1");
  if (opt_.across_faces && opt_.stiffness == SpringStiffness::Fitted)
    throw InvalidArgument("springs.connectivity: springs across faces take van-gelder stiffness, not fitted");
  if (!(opt_.face_share >= 0 && opt_.face_share < 1))
    throw InvalidArgument("springs.face_share: expected a value in [0, 1)");
  if (!(opt_.nodal_share >= 0 && opt_.nodal_share <= 1))
    throw InvalidArgument("springs.nodal_share: expected a value in [0, 1]");
  if (!(opt_.inversion_guard >= 0 && opt_.inversion_guard < 1))
    throw InvalidArgument("springs.inversion_guard: expected a volume ratio in [0, 1)");
  if (opt_.inversion_guard > 0 && !opt_.volume_term)
    throw InvalidArgument("springs.inversion_guard: acts beside a volume term, and there is none");

  // Headroom so the first cuts do not reallocate every per-vertex array (an O(n) hitch).
  const std::size_t nv = mesh.vertex_capacity(), nt = mesh.tet_capacity();
  for (auto* a : {&x_, &v_, &f_ext_, &target_, &acc_}) a->reserve(nv + nv / 4 + 64);
  for (auto* a : {&alive_, &fixed_, &prescribed_, &mark_}) a->reserve(nv + nv / 4 + 64);
  mass_.reserve(nv + nv / 4 + 64);
  bound_.reserve(nv + nv / 4 + 64);
  tet_v_.reserve(nt + nt / 4 + 64);
  tet_alive_.reserve(nt + nt / 4 + 64);
  if (opt_.stiffness == SpringStiffness::Fitted) tet_fit_.reserve(nt + nt / 4 + 64);
  volume_slot_.reserve(nt + nt / 4 + 64);
  grow_tree(nv + nv / 4 + 64);
  grow(nv, nt);
  for (std::uint32_t i = 0; i < mesh.vertex_capacity(); ++i) {
    if (!mesh.is_alive(VertexId(i))) continue;
    alive_[i] = 1;
    x_[i] = mesh.rest(VertexId(i));
  }
  spring_index_.reserve(mesh.num_vertices() * 8);
  springs_.reserve(mesh.num_vertices() * 8);
  for (std::uint32_t t = 0; t < mesh.tet_capacity(); ++t) {
    if (!mesh.is_alive(TetId(t))) continue;
    tet_v_[t] = mesh.tet_vertices(TetId(t));
    tet_alive_[t] = 1;
    fit_tet(mesh, TetId(t));
    if (opt_.volume_term) add_volume(mesh, TetId(t));
  }
  for (std::uint32_t t = 0; t < mesh.tet_capacity(); ++t) {
    if (!tet_alive_[t]) continue;
    const auto& tv = tet_v_[t];
    for (const auto& e : kEdges) {
      const std::uint32_t a = tv[e[0]].idx(), b = tv[e[1]].idx();
      if (!spring_index_.count(edge_key(a, b))) update_edge(mesh, a, b);
    }
  }
  if (opt_.across_faces)
    for (std::uint32_t t = 0; t < mesh.tet_capacity(); ++t) {
      if (!tet_alive_[t]) continue;
      for (int f = 0; f < 4; ++f) {
        const std::uint32_t a = tet_v_[t][f].idx(), p = apex_across(mesh, TetId(t), f);
        tet_partner_[t][f] = p;
        if (p != kNone && !spring_index_.count(face_key(a, p))) update_face_pair(mesh, a, p);
      }
    }
  for (std::uint32_t i = 0; i < mesh.vertex_capacity(); ++i)
    if (alive_[i]) update_mass(mesh, i);
  for (std::uint32_t i = 0; i < mesh.vertex_capacity(); ++i)
    if (alive_[i]) update_bound(mesh, i);
  counters_ = {};
}

const SpringCalibration& SpringModel::calibration(int label) const {
  auto it = calib_.find(label);
  if (it == calib_.end()) it = calib_.emplace(label, calibrate_springs(materials_.get(label), opt_)).first;
  return it->second;
}

void SpringModel::grow(std::size_t nv, std::size_t nt) {
  if (nv > x_.size()) {
    x_.resize(nv, Vec3::Zero());
    v_.resize(nv, Vec3::Zero());
    f_ext_.resize(nv, Vec3::Zero());
    target_.resize(nv, Vec3::Zero());
    acc_.resize(nv, Vec3::Zero());
    mass_.resize(nv, 0.0);
    alive_.resize(nv, 0);
    fixed_.resize(nv, 0);
    prescribed_.resize(nv, 0);
    mark_.resize(nv, 0);
    bound_.resize(nv, 0.0);
  }
  grow_tree(nv);
  if (opt_.stiffness == SpringStiffness::Fitted && nt > tet_fit_.size()) tet_fit_.resize(nt);
  if (nt > tet_v_.size()) {
    tet_v_.resize(nt);
    tet_alive_.resize(nt, 0);
    volume_slot_.resize(nt, kNone);
  }
  if (opt_.across_faces && nt > tet_partner_.size()) tet_partner_.resize(nt, {kNone, kNone, kNone, kNone});
}

void SpringModel::grow_tree(std::size_t nv) {
  if (nv <= bound_leaves_) return;
  // Doubling: the O(n) rebuild is amortized like vector growth.
  std::size_t leaves = std::max<std::size_t>(bound_leaves_, 1);
  while (leaves < nv) leaves *= 2;
  bound_leaves_ = leaves;
  bound_tree_.assign(2 * leaves, 0.0);
  for (std::size_t i = 0; i < bound_.size(); ++i) bound_tree_[leaves + i] = bound_[i];
  for (std::size_t i = leaves - 1; i >= 1; --i) bound_tree_[i] = std::max(bound_tree_[2 * i], bound_tree_[2 * i + 1]);
}

void SpringModel::set_bound(std::uint32_t v, double b) {
  bound_[v] = b;
  std::size_t i = bound_leaves_ + v;
  bound_tree_[i] = b;
  for (i /= 2; i >= 1; i /= 2) bound_tree_[i] = std::max(bound_tree_[2 * i], bound_tree_[2 * i + 1]);
}

// The spring of edge (a, b) from scratch: its star's tets, summed in the mesh's incidence
// order so a local update and a fresh build agree bit for bit on the same mesh.
void SpringModel::update_edge(const TetMesh& mesh, std::uint32_t a, std::uint32_t b) {
  if (a > b) std::swap(a, b);
  const std::uint64_t key = edge_key(a, b);
  double sum = 0, fitted = 0;
  SpringMix mix;
  bool any = false;
  if (mesh.is_alive(VertexId(a)) && mesh.is_alive(VertexId(b))) {
    // Scan the shorter incidence list (a deterministic choice, so still bit-reproducible).
    const auto ia = mesh.incident_tets(VertexId(a)), ib = mesh.incident_tets(VertexId(b));
    const bool use_b = ib.size() < ia.size();
    const std::uint32_t other = use_b ? a : b;
    for (TetId t : use_b ? ib : ia) {
      ++counters_.visits;
      const auto& tv = mesh.tet_vertices(t);
      if (tv[0].idx() != other && tv[1].idx() != other && tv[2].idx() != other && tv[3].idx() != other) continue;
      const double v = mesh.volume(t);
      if (opt_.stiffness == SpringStiffness::Fitted) {
        const int ia = mesh.local_index(t, VertexId(a)), ib = mesh.local_index(t, VertexId(b));
        fitted += tet_fit_[t.idx()].k[tet_edge_index(ia, ib)];
      } else {
        sum += calibration(mesh.label(t)).spring_modulus * v * edge_share(mesh, t);
      }
      mix.add(materials_.get(mesh.label(t)), v, opt_);
      any = true;
    }
  }
  if (!any) {
    remove_spring(key);
    return;
  }
  const double rest = (mesh.rest(VertexId(a)) - mesh.rest(VertexId(b))).norm();
  store_spring({a, b, rest, sum / (rest * rest) + fitted, mix.tau / mix.vol, mix.stiff / mix.vol, key});
}

void SpringModel::store_spring(const Spring& sp) {
  auto [it, inserted] = spring_index_.try_emplace(sp.key, static_cast<std::uint32_t>(springs_.size()));
  max_tau_ = std::max(max_tau_, sp.tau);
  if (inserted)
    springs_.push_back(sp);
  else
    springs_[it->second] = sp;
  ++counters_.visits;
}

double SpringModel::edge_share(const TetMesh& mesh, TetId t) const {
  if (!opt_.across_faces) return 1.0;
  int interior = 0;
  for (int f = 0; f < 4; ++f) interior += mesh.neighbor(t, f).is_valid();
  return 1.0 - opt_.face_share * interior / 4.0;
}

std::uint32_t SpringModel::apex_across(const TetMesh& mesh, TetId t, int f) const {
  const TetId n = mesh.neighbor(t, f);
  if (!n.is_valid()) return kNone;
  const auto face = mesh.face_vertices(t, f);
  for (VertexId w : mesh.tet_vertices(n))
    if (w != face[0] && w != face[1] && w != face[2]) return w.idx();
  return kNone;
}

// The spring across the faces whose apexes are a and b, from scratch: each such face has one
// tet at a, found among a's tets in the mesh's incidence order (bit-reproducible as edges).
// Each of the face's two tets gives it a quarter of face_share of its budget: 6 c V_t / 4.
void SpringModel::update_face_pair(const TetMesh& mesh, std::uint32_t a, std::uint32_t b) {
  if (a > b) std::swap(a, b);
  const std::uint64_t key = face_key(a, b);
  double sum = 0;
  SpringMix mix;
  bool any = false;
  if (mesh.is_alive(VertexId(a)) && mesh.is_alive(VertexId(b)))
    for (TetId t : mesh.incident_tets(VertexId(a))) {
      ++counters_.visits;
      const int f = mesh.local_index(t, VertexId(a));
      if (apex_across(mesh, t, f) != b) continue;
      for (TetId x : {t, mesh.neighbor(t, f)}) {
        const double v = mesh.volume(x);
        sum += opt_.face_share * 1.5 * calibration(mesh.label(x)).spring_modulus * v;
        mix.add(materials_.get(mesh.label(x)), v, opt_);
      }
      any = true;
    }
  if (!any) {
    remove_spring(key);
    return;
  }
  const double rest = (mesh.rest(VertexId(a)) - mesh.rest(VertexId(b))).norm();
  store_spring({a, b, rest, sum / (rest * rest), mix.tau / mix.vol, mix.stiff / mix.vol, key});
}

void SpringModel::remove_spring(std::uint64_t key) {
  auto it = spring_index_.find(key);
  if (it == spring_index_.end()) return;
  const std::uint32_t slot = it->second;
  spring_index_.erase(it);
  if (slot + 1 != springs_.size()) {
    springs_[slot] = springs_.back();
    spring_index_[springs_[slot].key] = slot;
  }
  springs_.pop_back();
  ++counters_.visits;
}

void SpringModel::fit_tet(const TetMesh& mesh, TetId t) {
  if (opt_.stiffness != SpringStiffness::Fitted) return;
  calibration(mesh.label(t));  // checks the material as the isotropic rule does
  const auto& tv = mesh.tet_vertices(t);
  const Material& m = materials_.get(mesh.label(t));
  tet_fit_[t.idx()] = fit_tet_springs({mesh.rest(tv[0]), mesh.rest(tv[1]), mesh.rest(tv[2]), mesh.rest(tv[3])}, m.mu(),
                                      m.lambda(), opt_.volume_term, opt_.min_volume_ratio * m.mu());
}

void SpringModel::add_volume(const TetMesh& mesh, TetId t) {
  const double kappa = opt_.stiffness == SpringStiffness::Fitted ? tet_fit_[t.idx()].kappa
                                                                 : calibration(mesh.label(t)).volume_modulus;
  if (!(kappa > 0)) return;
  const auto& tv = mesh.tet_vertices(t);
  volume_slot_[t.idx()] = static_cast<std::uint32_t>(volumes_.size());
  volumes_.push_back({{tv[0].idx(), tv[1].idx(), tv[2].idx(), tv[3].idx()}, mesh.volume(t), kappa, t.idx()});
  ++counters_.visits;
}

void SpringModel::remove_volume(TetId t) {
  const std::uint32_t slot = volume_slot_[t.idx()];
  if (slot == kNone) return;
  volume_slot_[t.idx()] = kNone;
  if (slot + 1 != volumes_.size()) {
    volumes_[slot] = volumes_.back();
    volume_slot_[volumes_[slot].tet] = slot;
  }
  volumes_.pop_back();
  ++counters_.visits;
}

void SpringModel::update_mass(const TetMesh& mesh, std::uint32_t v) {
  double m = 0;
  for (TetId t : mesh.incident_tets(VertexId(v))) {
    ++counters_.visits;
    m += materials_.get(mesh.label(t)).density * mesh.volume(t);
  }
  mass_[v] = 0.25 * m;
}

// Row v of Gershgorin's bound on M^-1 K at rest: (1/m_v) sum_j ||K_vj||, with ||K_vj|| <= k
// for each spring block (diagonal and off-diagonal) and kappa/V0 |g_v||g_j| for a volume
// block. It depends only on v's own mass, springs and tets, so an edit only changes the
// rows of the vertices it touches (the symmetric M^-1/2 K M^-1/2 form would drag in every
// neighbour of a vertex whose mass changed).
void SpringModel::update_bound(const TetMesh& mesh, std::uint32_t v) {
  if (!alive_[v] || !(mass_[v] > 0) || !mesh.is_alive(VertexId(v))) {
    set_bound(v, 0);
    return;
  }
  double row = 0;
  scratch_.clear();
  for (TetId t : mesh.incident_tets(VertexId(v))) {
    ++counters_.visits;
    const auto& tv = mesh.tet_vertices(t);
    for (VertexId w : tv)
      if (w.idx() != v && std::find(scratch_.begin(), scratch_.end(), w.idx()) == scratch_.end())
        scratch_.push_back(w.idx());
    const std::uint32_t slot = volume_slot_[t.idx()];
    if (slot == kNone) continue;
    const Volume& vol = volumes_[slot];
    const auto g = volume_gradient(mesh.rest(tv[0]), mesh.rest(tv[1]), mesh.rest(tv[2]), mesh.rest(tv[3]));
    const int li = mesh.local_index(t, VertexId(v));
    row += vol.kappa / vol.rest_volume * g[li].norm() *
           (g[0].norm() + g[1].norm() + g[2].norm() + g[3].norm());
  }
  for (std::uint32_t w : scratch_) {
    ++counters_.visits;
    auto it = spring_index_.find(edge_key(v, w));
    if (it != spring_index_.end()) row += 2 * springs_[it->second].k;
  }
  if (opt_.across_faces) {
    scratch_.clear();
    for (TetId t : mesh.incident_tets(VertexId(v))) {
      const std::uint32_t p = apex_across(mesh, t, mesh.local_index(t, VertexId(v)));
      if (p == kNone || std::find(scratch_.begin(), scratch_.end(), p) != scratch_.end()) continue;
      scratch_.push_back(p);
      auto it = spring_index_.find(face_key(v, p));
      if (it != spring_index_.end()) row += 2 * springs_[it->second].k;
    }
  }
  set_bound(v, row / mass_[v]);
}

void SpringModel::apply(const TetMesh& mesh, const TopologyChange& change) {
  follower_.follow(mesh, change);
  ++counters_.updates;
  grow(mesh.vertex_capacity(), mesh.tet_capacity());
  touched_.clear();
  edge_scratch_.clear();
  auto touch = [&](std::uint32_t v) {
    if (mark_[v]) return;
    mark_[v] = 1;
    touched_.push_back(v);
  };
  for (const VertexOrigin& o : change.added_vertices) {
    const std::uint32_t i = o.vertex.idx();
    const Vec3 zero = Vec3::Zero();
    Vec3 x = interpolate_origin(o, zero, [&](VertexId p) { return x_[p.idx()]; });
    const Vec3 u = interpolate_origin(o, zero, [&](VertexId p) { return v_[p.idx()]; });
    const Vec3 target = interpolate_origin(o, zero, [&](VertexId p) { return target_[p.idx()]; });
    const bool any = has_parents(o);
    bool all_fixed = true, all_prescribed = true;
    for (int k = 0; k < 4; ++k)
      if (o.parents[k].is_valid() && o.weights[k] != 0) {
        all_fixed = all_fixed && fixed_[o.parents[k].idx()];
        all_prescribed = all_prescribed && prescribed_[o.parents[k].idx()];
      }
    if (!any) x = mesh.rest(o.vertex);  // no parents: a plain new vertex starts at rest
    alive_[i] = 1;
    x_[i] = x;
    v_[i] = any ? u : Vec3::Zero();
    fixed_[i] = any && all_fixed;
    prescribed_[i] = any && all_prescribed && !fixed_[i];
    target_[i] = target;
    f_ext_[i] = Vec3::Zero();
    mass_[i] = 0;
    touch(i);
  }
  // Moved vertices (smoothing): the deformation at the new rest position, so the current
  // shape does not change.
  for (const VertexOrigin& o : change.moved_vertices) {
    const std::uint32_t i = o.vertex.idx();
    const Vec3 zero = Vec3::Zero();
    const Vec3 x = interpolate_origin(o, zero, [&](VertexId p) { return x_[p.idx()]; });
    const Vec3 u = interpolate_origin(o, zero, [&](VertexId p) { return v_[p.idx()]; });
    const Vec3 target = interpolate_origin(o, zero, [&](VertexId p) { return target_[p.idx()]; });
    x_[i] = x;
    v_[i] = u;
    if (prescribed_[i]) target_[i] = target;
    touch(i);
  }
  // Removals last: a vertex the batch added and then removed (contracted) is in both lists.
  for (VertexId v : change.removed_vertices) {
    const std::uint32_t i = v.idx();
    alive_[i] = fixed_[i] = prescribed_[i] = 0;
    mass_[i] = 0;
    touch(i);
  }
  auto add_edges = [&](const std::array<VertexId, 4>& tv) {
    for (const auto& e : kEdges) edge_scratch_.push_back(edge_key(tv[e[0]].idx(), tv[e[1]].idx()));
    for (VertexId w : tv) touch(w.idx());
  };
  // across_faces: the springs across the faces of every tet the change removed (the apexes as
  // they were) and, after the lists, of every face of a removed or added tet as it is now.
  std::vector<std::uint64_t> pairs;
  std::vector<std::array<std::uint32_t, 3>> faces;
  auto forget_tet = [&](std::uint32_t t) {
    if (!opt_.across_faces) return;
    const auto& tv = tet_v_[t];
    for (int f = 0; f < 4; ++f) {
      std::array<std::uint32_t, 3> face{};
      for (int j = 0, k = 0; j < 4; ++j)
        if (j != f) face[k++] = tv[j].idx();
      std::sort(face.begin(), face.end());
      faces.push_back(face);
      if (tet_partner_[t][f] != kNone) pairs.push_back(face_key(tv[f].idx(), tet_partner_[t][f]));
      tet_partner_[t][f] = kNone;
    }
  };
  // Removed first: a recycled id appears in both lists.
  for (TetId t : change.removed_tets) {
    ++counters_.visits;
    if (!tet_alive_[t.idx()]) continue;
    add_edges(tet_v_[t.idx()]);
    forget_tet(t.idx());
    tet_alive_[t.idx()] = 0;
    remove_volume(t);
  }
  for (TetId t : change.added_tets) {
    ++counters_.visits;
    if (tet_alive_[t.idx()]) {  // not listed as removed (a change applied twice): replace it
      add_edges(tet_v_[t.idx()]);
      forget_tet(t.idx());
      remove_volume(t);
    }
    tet_v_[t.idx()] = mesh.tet_vertices(t);
    tet_alive_[t.idx()] = 1;
    fit_tet(mesh, t);
    add_edges(tet_v_[t.idx()]);
    forget_tet(t.idx());  // lists its faces; it has no springs yet
    if (opt_.volume_term) add_volume(mesh, t);
  }
  for (VertexId v : change.touched_vertices) touch(v.idx());
  if (opt_.across_faces) {
    // The live tets on each listed face now: their apex across it (and so the springs at both
    // ends), and their edges' share (a face that opened or closed changes it).
    std::sort(faces.begin(), faces.end());
    faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
    for (const auto& face : faces) {
      if (!mesh.is_alive(VertexId(face[0]))) continue;
      for (TetId x : mesh.incident_tets(VertexId(face[0]))) {
        ++counters_.visits;
        const int i1 = mesh.local_index(x, VertexId(face[1])), i2 = mesh.local_index(x, VertexId(face[2]));
        if (i1 < 0 || i2 < 0) continue;
        const int f = 6 - mesh.local_index(x, VertexId(face[0])) - i1 - i2;  // the corner off the face
        const std::uint32_t apex = mesh.tet_vertices(x)[f].idx(), old = tet_partner_[x.idx()][f];
        const std::uint32_t now = apex_across(mesh, x, f);
        if (old != kNone) pairs.push_back(face_key(apex, old));
        if (now != kNone) pairs.push_back(face_key(apex, now));
        tet_partner_[x.idx()][f] = now;
        add_edges(mesh.tet_vertices(x));
      }
    }
    std::sort(pairs.begin(), pairs.end());
    pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
    for (std::uint64_t key : pairs) {
      const auto a = static_cast<std::uint32_t>((key & ~kFaceBit) >> 32), b = static_cast<std::uint32_t>(key & 0xffffffffu);
      update_face_pair(mesh, a, b);
      touch(a);
      touch(b);
    }
  }

  std::sort(edge_scratch_.begin(), edge_scratch_.end());
  edge_scratch_.erase(std::unique(edge_scratch_.begin(), edge_scratch_.end()), edge_scratch_.end());
  for (std::uint64_t key : edge_scratch_)
    update_edge(mesh, static_cast<std::uint32_t>(key >> 32), static_cast<std::uint32_t>(key & 0xffffffffu));

  for (std::uint32_t v : touched_) {
    if (alive_[v] && mesh.is_alive(VertexId(v)))
      update_mass(mesh, v);
    else
      mass_[v] = 0;
  }
  for (std::uint32_t v : touched_) update_bound(mesh, v);
  for (std::uint32_t v : touched_) mark_[v] = 0;
  invalidate();
}

void SpringModel::set_fixed(VertexId v, bool fixed) {
  fixed_[v.idx()] = fixed;
  if (fixed) {
    prescribed_[v.idx()] = 0;
    v_[v.idx()] = Vec3::Zero();
  }
  invalidate();
}

void SpringModel::set_prescribed(VertexId v, const Vec3& position) {
  prescribed_[v.idx()] = 1;
  fixed_[v.idx()] = 0;
  target_[v.idx()] = position;
  invalidate();
}

void SpringModel::clear_prescribed(VertexId v) {
  prescribed_[v.idx()] = 0;
  invalidate();
}

void SpringModel::set_external_force(VertexId v, const Vec3& f) {
  f_ext_[v.idx()] = f;
  invalidate();
}

void SpringModel::set_gravity(const Vec3& g) {
  gravity_ = g;
  invalidate();
}

void SpringModel::set_position(VertexId v, const Vec3& x) {
  x_[v.idx()] = x;
  invalidate();
}

void SpringModel::set_velocity(VertexId v, const Vec3& u) {
  v_[v.idx()] = u;
  invalidate();
}

std::optional<SpringModel::SpringInfo> SpringModel::spring(VertexId a, VertexId b) const {
  auto it = spring_index_.find(edge_key(a.idx(), b.idx()));
  if (it == spring_index_.end()) return std::nullopt;
  const Spring& s = springs_[it->second];
  return SpringInfo{VertexId(s.a), VertexId(s.b), s.rest, s.k, s.tau, s.stiffening, false};
}

std::optional<SpringModel::SpringInfo> SpringModel::spring_across_faces(VertexId a, VertexId b) const {
  auto it = spring_index_.find(face_key(a.idx(), b.idx()));
  if (it == spring_index_.end()) return std::nullopt;
  const Spring& s = springs_[it->second];
  return SpringInfo{VertexId(s.a), VertexId(s.b), s.rest, s.k, s.tau, s.stiffening, true};
}

std::vector<SpringModel::SpringInfo> SpringModel::springs() const {
  std::vector<SpringInfo> out;
  out.reserve(springs_.size());
  for (const Spring& s : springs_)
    out.push_back({VertexId(s.a), VertexId(s.b), s.rest, s.k, s.tau, s.stiffening, (s.key & kFaceBit) != 0});
  std::sort(out.begin(), out.end(), [](const SpringInfo& p, const SpringInfo& q) {
    return p.a != q.a ? p.a < q.a : p.b != q.b ? p.b < q.b : p.across_faces < q.across_faces;
  });
  return out;
}

std::optional<SpringModel::VolumeInfo> SpringModel::volume_term(TetId t) const {
  if (t.idx() >= volume_slot_.size() || volume_slot_[t.idx()] == kNone) return std::nullopt;
  const Volume& v = volumes_[volume_slot_[t.idx()]];
  return VolumeInfo{t, v.rest_volume, v.kappa};
}

// W = kappa V0 (J - 1 - ln J): zero with zero slope at J = 1, curvature kappa V0 there (the
// linear bulk term), infinite at J -> 0. Below barrier_limit: its quadratic Taylor expansion.
double SpringModel::barrier_energy(double J, double kappa, double V0) const {
  const double jm = opt_.barrier_limit;
  if (J >= jm) return kappa * V0 * (J - 1 - std::log(J));
  const double d = J - jm;
  return kappa * V0 * ((jm - 1 - std::log(jm)) + (1 - 1 / jm) * d + 0.5 * d * d / (jm * jm));
}

double SpringModel::barrier_slope(double J, double kappa, double V0) const {
  const double jm = opt_.barrier_limit;
  if (J >= jm) return kappa * V0 * (1 - 1 / J);
  return kappa * V0 * ((1 - 1 / jm) + (J - jm) / (jm * jm));
}

double SpringModel::spring_tension(const Spring& s, double l) const {
  const double e = (l - s.rest) / s.rest, b = s.stiffening;
  return b > 0 ? s.k * s.rest * std::expm1(b * e) / b : s.k * (l - s.rest);
}

double SpringModel::spring_energy(const Spring& s, double l) const {
  const double e = (l - s.rest) / s.rest, b = s.stiffening;
  return b > 0 ? s.k * s.rest * s.rest * (std::expm1(b * e) - b * e) / (b * b) : 0.5 * s.k * (l - s.rest) * (l - s.rest);
}

double SpringModel::spring_axial(const Spring& s, double l) const {
  return s.stiffening > 0 ? std::exp(s.stiffening * (l - s.rest) / s.rest) : 1.0;
}

double SpringModel::barrier_curvature(double J, double kappa, double V0) const {
  const double j = std::max(J, opt_.barrier_limit);
  return kappa * V0 / (j * j);
}

// The guard is the barrier of J / j scaled by j: W = j W_b(J / j), zero with zero slope at
// J = j, curvature kappa V0 / j there, unbounded as J -> 0 (the barrier's Taylor tail below
// barrier_limit of j).
double SpringModel::guard_energy(double J, double kappa, double V0) const {
  const double j = opt_.inversion_guard;
  return j > 0 && J < j ? j * barrier_energy(J / j, kappa, V0) : 0.0;
}

double SpringModel::guard_slope(double J, double kappa, double V0) const {
  const double j = opt_.inversion_guard;
  return j > 0 && J < j ? barrier_slope(J / j, kappa, V0) : 0.0;
}

double SpringModel::guard_curvature(double J, double kappa, double V0) const {
  const double j = opt_.inversion_guard;
  return j > 0 && J < j ? barrier_curvature(J / j, kappa, V0) / j : 0.0;
}

std::array<Vec3, 4> SpringModel::volume_gradient_of(const Volume& vol) const {
  return volume_gradient(x_[vol.v[0]], x_[vol.v[1]], x_[vol.v[2]], x_[vol.v[3]]);
}

void SpringModel::compute_forces(const std::vector<Vec3>& x, const std::vector<Vec3>& v, std::vector<Vec3>& f) const {
  const std::size_t n = x.size();
  f.resize(n);
  const double c = opt_.damping;
  for (std::size_t i = 0; i < n; ++i)
    f[i] = active(static_cast<std::uint32_t>(i)) ? Vec3(mass_[i] * (gravity_ - c * v[i]) + f_ext_[i]) : Vec3::Zero();
  for (const Spring& s : springs_) {
    const Vec3 d = x[s.a] - x[s.b];
    const double l = d.norm();
    if (!(l > 0)) continue;  // coincident ends: no direction, no force
    double t = -spring_tension(s, l);  // along d, on a
    if (s.tau > 0) t -= s.tau * s.k * d.dot(v[s.a] - v[s.b]) / l;
    const Vec3 fs = (t / l) * d;
    f[s.a] += fs;
    f[s.b] -= fs;
  }
  const double own = tet_part();
  if (opt_.nodal_volume) nodal_volumes(x);
  for (const Volume& vol : volumes_) {
    const Vec3 &x0 = x[vol.v[0]], &x1 = x[vol.v[1]], &x2 = x[vol.v[2]], &x3 = x[vol.v[3]];
    const auto g = volume_gradient(x0, x1, x2, x3);
    double s = 0;  // dW/dV_t: the tet's own barrier, and a quarter of each corner's nodal slope
    const double J = (x1 - x0).dot(g[1]) / vol.rest_volume;
    if (own > 0) s = barrier_slope(J, own * vol.kappa, vol.rest_volume) / vol.rest_volume;
    s += guard_slope(J, vol.kappa, vol.rest_volume) / vol.rest_volume;
    if (opt_.nodal_volume)
      for (int k = 0; k < 4; ++k) s += 0.25 * nodal_[vol.v[k]].slope;
    for (int k = 0; k < 4; ++k) f[vol.v[k]] -= s * g[k];
  }
}

void SpringModel::nodal_volumes(const std::vector<Vec3>& x) const {
  nodal_.assign(x.size(), {});
  for (const Volume& vol : volumes_) {
    const double v = signed_volume(x[vol.v[0]], x[vol.v[1]], x[vol.v[2]], x[vol.v[3]]);
    for (std::uint32_t a : vol.v) {
      NodalVolume& n = nodal_[a];
      n.rest += 0.25 * vol.rest_volume;
      n.kappa_rest += 0.25 * nodal_part() * vol.kappa * vol.rest_volume;
      n.current += 0.25 * v;
    }
  }
  for (NodalVolume& n : nodal_) {
    if (!(n.rest > 0)) continue;
    const double kappa = n.kappa_rest / n.rest, J = n.current / n.rest;
    n.slope = barrier_slope(J, kappa, n.rest) / n.rest;
    n.beta = barrier_curvature(J, kappa, n.rest) / (n.rest * n.rest);
  }
}

double SpringModel::kinetic_energy() const {
  double e = 0;
  for (std::size_t i = 0; i < x_.size(); ++i)
    if (active(static_cast<std::uint32_t>(i))) e += 0.5 * mass_[i] * v_[i].squaredNorm();
  return e;
}

double SpringModel::potential_energy() const {
  double e = 0;
  for (const Spring& s : springs_) e += spring_energy(s, (x_[s.a] - x_[s.b]).norm());
  if (opt_.nodal_volume) {
    nodal_volumes(x_);
    for (const NodalVolume& n : nodal_)
      if (n.rest > 0) e += barrier_energy(n.current / n.rest, n.kappa_rest / n.rest, n.rest);
  }
  if (const double own = tet_part(); own > 0 || opt_.inversion_guard > 0)
    for (const Volume& vol : volumes_) {
      const double J = signed_volume(x_[vol.v[0]], x_[vol.v[1]], x_[vol.v[2]], x_[vol.v[3]]) / vol.rest_volume;
      if (own > 0) e += barrier_energy(J, own * vol.kappa, vol.rest_volume);
      e += guard_energy(J, vol.kappa, vol.rest_volume);
    }
  for (std::size_t i = 0; i < x_.size(); ++i)
    if (active(static_cast<std::uint32_t>(i))) e -= (mass_[i] * gravity_ + f_ext_[i]).dot(x_[i]);
  return e;
}

}  // namespace incise
