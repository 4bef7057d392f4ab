#include "scene/scene_runner.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <sstream>
#include <unordered_map>
#include <utility>

#include "mesh/clock.h"
#include "mesh/errors.h"
#include "mesh/rest_bounds.h"

namespace incise {

namespace {

// Content errors name the scene file and the key, as the parser's do.
[[noreturn]] void fail(const Scene& s, const std::string& key, const std::string& what) {
  throw IoError(s.path, 0, key + ": " + what);
}

// A vertex moved by more than this many times the body's size (the diagonal of its rest
// bounding box) means the solution blew up: no scene asks for that, while a free part under a
// static solve, an explicit step above the stable limit or loads far beyond the material do.
constexpr double kBlowUpFactor = 1e3;

// Largest vertex displacement in `disp` (3 per vertex slot); NaN when any is NaN (std::max
// would skip it), infinite when any is infinite.
double max_displacement(const Eigen::VectorXd& disp) {
  double d = 0;
  for (Eigen::Index i = 0; i + 2 < disp.size(); i += 3) {
    const double n = disp.segment<3>(i).norm();
    if (std::isnan(n)) return n;
    d = std::max(d, n);
  }
  return d;
}

// Tets whose deformed shape (rest + disp) has a volume <= 0: inverted or flat. One pass over
// the tets, like the frame's solve (docs/scene.md, stats.csv's `inverted`).
std::size_t count_inverted(const TetMesh& mesh, const Eigen::VectorXd& disp) {
  std::size_t n = 0;
  for (TetId t : mesh.tets()) {
    const auto& v = mesh.tet_vertices(t);
    auto x = [&](int k) { return Vec3(mesh.rest(v[k]) + disp.segment<3>(3 * v[k].idx())); };
    const Vec3 p0 = x(0);
    Eigen::Matrix3d m;
    m.col(0) = x(1) - p0;
    m.col(1) = x(2) - p0;
    m.col(2) = x(3) - p0;
    n += m.determinant() <= 0;
  }
  return n;
}

// Throws when a frame's solution blew up: a non-finite displacement or residual, or a vertex
// moved by more than kBlowUpFactor times the body's size. Such a frame is never "converged".
void check_solution(const Scene& s, int frame, double max_disp, double residual, double size) {
  if (max_disp <= kBlowUpFactor * size && std::isfinite(residual)) return;  // false for NaN too
  std::ostringstream m;
  m << s.path << ": frame " << frame << ": the solution blew up (";
  if (!std::isfinite(max_disp)) m << "a displacement is NaN or infinite";
  else if (!std::isfinite(residual)) m << "relative residual " << residual;
  else {
    const double times = max_disp / size;
    m << std::setprecision(2) << "max displacement " << max_disp << ", ";
    if (times < 1e6) m << std::fixed << std::setprecision(0);
    m << times << "x the body's size" << std::defaultfloat;
  }
  m << "); ";
  if (s.model == SceneModel::Springs)
    m << "reduce time.dt or raise time.substeps, or check the loads";
  else if (s.integrator == "static")
    m << "check that every part is fixed or probed and that the loads suit the materials";
  else
    m << "reduce time.dt, or check the loads";
  throw Error(m.str());
}

// The message for a part a cut detached that holds no fixed or prescribed vertex; `why` ends it.
std::string detached_part(const Scene& s, int frame, std::size_t tets, const Vec3& near, const std::string& why) {
  std::ostringstream m;
  m << s.path << ": frame " << frame << ": a cut detached a part of " << tets << " tets near (" << std::setprecision(3)
    << near.x() << ", " << near.y() << ", " << near.z() << ") with no fixed vertex" << why;
  return m.str();
}

// The boundary faces a pressure or traction load selects: by tag, or all three corners in its box.
std::vector<std::array<VertexId, 3>> selected_faces(const TetMesh& mesh, const SceneLoad& l, double tol, const Scene& s) {
  std::vector<std::array<VertexId, 3>> out;
  for (const BoundaryFace& f : mesh.boundary_faces()) {
    bool in = l.tag >= 0 ? f.tag == l.tag : true;
    if (l.tag < 0)
      for (VertexId v : f.vertices) in = in && l.box.contains(mesh.rest(v), tol);
    if (in) out.push_back({f.vertices[0], f.vertices[1], f.vertices[2]});
  }
  if (out.empty())
    fail(s, l.key + (l.tag >= 0 ? ".tag" : ".box"),
         l.tag >= 0 ? "no boundary face has tag " + std::to_string(l.tag) : std::string("selects no boundary face"));
  return out;
}

// Per corner vertex of the selected faces, a third of each face's rest area: as a vector
// (outward), whose negative is the force of a unit pressure, and as a number, the force of a
// unit traction.
std::vector<FaceShare> face_shares(const TetMesh& mesh, const std::vector<std::array<VertexId, 3>>& faces) {
  std::unordered_map<std::uint32_t, FaceShare> w;
  for (const auto& f : faces) {
    const Vec3 a = mesh.rest(f[0]), b = mesh.rest(f[1]), c = mesh.rest(f[2]);
    const Vec3 area = 0.5 * (b - a).cross(c - a);
    for (VertexId v : f) {
      FaceShare& share = w.try_emplace(v.idx(), FaceShare{v, Vec3::Zero(), 0.0}).first->second;  // Eigen leaves a default Vec3 unset
      share.area_vector += area / 3;
      share.area += area.norm() / 3;
    }
  }
  std::vector<FaceShare> out;
  for (const auto& [v, share] : w) out.push_back(share);
  std::sort(out.begin(), out.end(), [](const FaceShare& x, const FaceShare& y) { return x.vertex.idx() < y.vertex.idx(); });
  return out;
}

// Fraction of a scene blade's sweep done when `frame` is solved.
double sweep_fraction(const SceneCut& c, int frame) {
  if (frame < c.from_frame) return 0;
  if (c.to_frame <= c.from_frame || frame >= c.to_frame) return 1;
  return double(frame - c.from_frame + 1) / double(c.to_frame - c.from_frame + 1);
}

// Where a path cut's blade is at `frame` (linear between the keys around it).
BladeSegment path_blade(const SceneCut& c, int frame) {
  const auto& p = c.path;
  if (frame <= p.front().frame) return {p.front().a, p.front().b};
  for (std::size_t i = 1; i < p.size(); ++i)
    if (frame <= p[i].frame) {
      const double t = double(frame - p[i - 1].frame) / double(p[i].frame - p[i - 1].frame);
      return {(1 - t) * p[i - 1].a + t * p[i].a, (1 - t) * p[i - 1].b + t * p[i].b};
    }
  return {p.back().a, p.back().b};
}

}  // namespace

SceneRunner::SceneRunner(const Scene& scene, const TetMesh* mesh) : scene_(scene) {
  const Scene& s = scene_;
  // ---- mesh ---------------------------------------------------------------------------
  if (mesh) mesh_ = *mesh;
  else mesh_ = load_scene_mesh(s);
  mesh_.discard_change();
  if (mesh_.num_tets() == 0) fail(s, "mesh", "the mesh has no tetrahedra");

  // ---- boxes -> vertex sets (checked before anything is written) -----------------------
  const RestBounds box = rest_bounds(mesh_);
  const Vec3 lo = box.lo, hi = box.hi;
  size_ = box.size().norm();  // the body's size, for the blow-up check
  const double tol = 1e-9 * size_;
  auto select = [&](const SceneBox& b, const std::string& key) {
    std::vector<VertexId> out;
    for (VertexId v : mesh_.vertices())
      if (!mesh_.incident_tets(v).empty() && b.contains(mesh_.rest(v), tol)) out.push_back(v);
    if (out.empty()) {
      std::ostringstream m;
      m << "selects no vertex; the mesh spans [" << lo.x() << ", " << lo.y() << ", " << lo.z() << "] to [" << hi.x() << ", "
        << hi.y() << ", " << hi.z() << "]";
      fail(s, key, m.str());
    }
    return out;
  };
  std::vector<std::pair<VertexId, unsigned>> fixed;  // vertex, held axes
  for (std::size_t i = 0; i < s.fixed.size(); ++i)
    for (VertexId v : select(s.fixed[i].box, "fixed[" + std::to_string(i) + "].box")) fixed.emplace_back(v, s.fixed[i].axes);
  load_vertices_.resize(s.loads.size());
  // Pressure and traction loads: per vertex, its share of the selected faces' rest areas (a third
  // per corner), fixed when the scene starts like other loads.
  face_shares_.resize(s.loads.size());
  Vec3 gravity = Vec3::Zero();
  for (std::size_t i = 0; i < s.loads.size(); ++i) {
    const SceneLoad& l = s.loads[i];
    if (l.kind == SceneLoad::Kind::Gravity) gravity += l.value;
    else if (l.kind == SceneLoad::Kind::Pressure || l.kind == SceneLoad::Kind::Traction) {
      // Quadratic tets take the faces themselves (consistent loads on their mid-edge nodes).
      auto faces = selected_faces(mesh_, l, tol, s);
      face_shares_[i] = face_shares(mesh_, faces);
      if (is_quadratic(s.formulation) && s.model != SceneModel::Springs) {
        face_lists_.resize(s.loads.size());
        face_lists_[i] = std::move(faces);
      }
    }
    else load_vertices_[i] = select(l.box, l.key + ".box");
  }

  // ---- model (only the one the scene uses) ---------------------------------------------
  if (s.model == SceneModel::Springs) {
    SpringOptions so;
    so.damping = s.damping;
    so.cg_tolerance = s.cg.tolerance;
    so.cg_max_iterations = s.cg.max_iterations;
    so.compute_energy = false;
    so.volume_term = s.springs_volume != "none";
    so.nodal_volume = s.springs_volume == "nodal";
    so.nodal_share = s.springs_nodal_share;
    so.inversion_guard = s.springs_inversion_guard;
    so.stiffness = parse_spring_stiffness(s.springs_stiffness).value_or(SpringStiffness::VanGelder);
    so.across_faces = s.springs_connectivity == "across-faces";
    so.viscosity = s.springs_viscosity;
    so.stiffening = s.springs_stiffening;
    springs_ = std::make_unique<SpringModel>(mesh_, s.materials, so);
    integrator_ = parse_integrator(s.integrator);
    for (const auto& [v, axes] : fixed) springs_->set_fixed(v, true);  // axes == 7: the parser refuses rollers
    springs_->set_gravity(gravity);
  } else {
    FemSimulationOptions fo;
    fo.kind = s.model == SceneModel::FemCorotational ? FemKind::Corotational : FemKind::Linear;
    fo.formulation = s.formulation;
    fo.method = s.method;
    fo.backend = s.backend;
    fo.petsc_options = s.petsc_options;
    fo.cg = s.cg;
    fo.warm_start = s.warm_start;
    fo.predict = s.predict;
    fo.dynamic = s.integrator == "implicit-euler";
    fo.dt = s.dt;
    fo.damping = s.damping;
    fo.nonlinear_iterations = s.nonlinear_iterations;
    fo.inversion_barrier = s.inversion_barrier;
    fo.cholesky = s.cholesky;
    fo.amg = s.amg;
    fo.gravity = gravity;
    fem_ = std::make_unique<FemSimulation>(mesh_, s.materials, fo);
    for (const auto& [v, axes] : fixed) fem_->constrain(v, axes);
    for (std::size_t i = 0; i < s.loads.size(); ++i)
      if (s.loads[i].kind == SceneLoad::Kind::Probe)
        for (VertexId v : load_vertices_[i]) fem_->prescribe(v, Vec3::Zero());
    if (!fo.dynamic) {
      try {
        fem_->check_constraints();
      } catch (const InvalidArgument& e) {
        fail(s, "fixed", e.what());
      }
    }
  }
  dynamic_ = s.model == SceneModel::Springs || s.integrator == "implicit-euler";
  policy_ = s.fragments;
  if (policy_ == FragmentPolicy::Auto) policy_ = dynamic_ ? FragmentPolicy::Keep : FragmentPolicy::Remove;

  // Every scene blade's cutter (and its first-contact grid, O(mesh)) is made here, as setup;
  // afterwards each step's change is passed to the other cutters, so no grid goes stale (only
  // a fragment removal makes them rebuild).
  for (const SceneCut& c : s.cuts) {
    CutOptions o;
    o.mode = c.mode == "remove" ? CutMode::Remove : CutMode::Subdivide;
    o.snap = c.snap;
    o.improve = c.improve;
    o.exact_volumes = c.exact_volumes;
    o.provisional = c.provisional;
    o.material_frame = c.material_frame;
    o.finish_improve_slice = kFinishImproveSlice;
    o.improve_budget_ms = improve_time_cap();
    cutters_.push_back(std::make_unique<Cutter>(mesh_, o));
    cutters_.back()->start({c.a, c.b});
  }
  swept_.assign(s.cuts.size(), 0.0);
  cut_tallies_.assign(s.cuts.size(), {});
}

SceneRunner::~SceneRunner() = default;

Vec3 SceneRunner::position(VertexId v) const {
  if (fem_) return mesh_.rest(v) + fem_->displacement().segment<3>(3 * v.idx());
  return springs_->positions()[v.idx()];
}

std::vector<Vec3> SceneRunner::positions() const {
  std::vector<Vec3> x(mesh_.vertex_capacity(), Vec3::Zero());
  for (VertexId v : mesh_.vertices()) x[v.idx()] = position(v);
  return x;
}

std::vector<VertexId> SceneRunner::loaded_vertices() const {
  std::vector<VertexId> out;
  for (const auto& list : load_vertices_) out.insert(out.end(), list.begin(), list.end());
  for (const auto& shares : face_shares_)
    for (const FaceShare& w : shares) out.push_back(w.vertex);
  std::sort(out.begin(), out.end(), [](VertexId a, VertexId b) { return a.idx() < b.idx(); });
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

std::vector<VertexId> SceneRunner::vertices_near(const Vec3& point, double radius) const {
  std::vector<VertexId> out;
  for (VertexId v : mesh_.vertices())
    if (!mesh_.incident_tets(v).empty() && (position(v) - point).norm() <= radius) out.push_back(v);
  return out;
}

// One pass over the state vector, like a CG iteration's vector update (interpolated new
// vertices never exceed it, so it holds through a frame's cuts).
double SceneRunner::max_displacement_bound() const {
  double d = 0;
  if (fem_) {
    const Eigen::VectorXd& u = fem_->displacement();
    for (Eigen::Index i = 0; i + 2 < u.size(); i += 3) d = std::max(d, u.segment<3>(i).squaredNorm());
  } else {
    for (VertexId v : mesh_.vertices()) d = std::max(d, (springs_->positions()[v.idx()] - mesh_.rest(v)).squaredNorm());
  }
  return std::sqrt(d);
}

// A change made by cutter `from` (null: not a cutter) goes to the other cutters' grids and to
// the backend, which updates locally.
void SceneRunner::apply_change(const TopologyChange& change, const Cutter* from) {
  if (change.empty()) return;
  for (const auto& c : cutters_)
    if (c.get() != from) c->notify(change);
  if (blade_ && blade_.get() != from) blade_->notify(change);
  if (fem_) fem_->apply(change);
  else springs_->apply(mesh_, change);
  if (observer_) observer_(change);
}

bool SceneRunner::held_by_scene(VertexId v) const {
  if (fem_) return fem_->is_constrained(v);
  if (springs_->is_fixed(v)) return true;
  for (std::size_t i = 0; i < scene_.loads.size(); ++i)
    if (scene_.loads[i].kind == SceneLoad::Kind::Probe &&
        std::find(load_vertices_[i].begin(), load_vertices_[i].end(), v) != load_vertices_[i].end())
      return true;
  return false;
}

// Detached parts without a fixed or prescribed vertex follow the scene's fragment policy (a
// static solve has no equilibrium for a free part). Named by the frame they come before.
void SceneRunner::handle_fragments(std::vector<std::vector<TetId>> parts, std::vector<TetId> body) {
  const Scene& s = scene_;
  const auto holds = [&](const std::vector<TetId>& part) {
    for (TetId t : part)
      if (mesh_.is_alive(t))
        for (VertexId v : mesh_.tet_vertices(t))
          if (fem_ ? fem_->is_constrained(v) : springs_->is_fixed(v)) return true;
    return false;
  };
  // A small body cut through: the cutter took its largest part for the body, but where the
  // scene holds a smaller one and not that one, the body is what came loose.
  if (!body.empty() && !holds(body) && std::any_of(parts.begin(), parts.end(), holds))
    parts.push_back(std::move(body));
  for (const auto& part : parts) {
    if (holds(part)) continue;
    std::vector<VertexId> verts;
    std::size_t tets = 0;
    Vec3 near = Vec3::Zero();  // the rest-space centroid of its tets' corners, for messages
    for (TetId t : part) {
      if (!mesh_.is_alive(t)) continue;
      ++tets;
      for (VertexId v : mesh_.tet_vertices(t)) {
        verts.push_back(v);
        near += mesh_.rest(v);
      }
    }
    if (verts.empty()) continue;
    near /= double(verts.size());
    // Keep is for dynamic scenes, where a free part falls; a static solve has no equilibrium
    // for it (K is singular there) and would return garbage that looks converged.
    if (policy_ == FragmentPolicy::Keep && !dynamic_)
      throw Error(detached_part(s, frame_, tets, near,
                                "; a static solve has no equilibrium for it (set \"fragments\" to \"remove\" or "
                                "\"fix\", or use a dynamic integrator)"));
    if (policy_ == FragmentPolicy::Keep) continue;
    ++fragments_handled_;
    if (policy_ == FragmentPolicy::Error)
      throw Error(detached_part(s, frame_, tets, near, " (set \"fragments\" to \"remove\", \"fix\" or \"keep\")"));
    if (policy_ == FragmentPolicy::Fix) {
      for (VertexId v : verts) {
        if (fem_) fem_->fix(v);
        else springs_->set_fixed(v, true);
      }
    } else {  // Remove
      for (TetId t : part)
        if (mesh_.is_alive(t)) mesh_.remove_tet(t);
      std::sort(verts.begin(), verts.end());
      verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
      for (VertexId v : verts)
        if (mesh_.is_alive(v) && mesh_.incident_tets(v).empty()) mesh_.remove_vertex(v);
      // The backend takes the removal; the cutters notice it by the mesh's edit counter.
      const TopologyChange ch = mesh_.take_change();
      if (!ch.empty()) {
        if (fem_) fem_->apply(ch);
        else springs_->apply(mesh_, ch);
        if (observer_) observer_(ch);
      }
    }
  }
}

// Before frame_'s solve every scene blade advances to its position at that frame (linear from
// from_frame to to_frame), cutting the current shape; a sweep that is done is finished (the
// blade withdrawn, its front released). Returns the cutting time.
double SceneRunner::cut_scene_blades(double& improve_ms) {
  const auto current = [this](VertexId v) { return position(v); };
  double ms = 0;
  double bound = -1;  // measured once, in the first step that needs it
  // A step's detached parts are handled before the next cutter call: that call (a finish()
  // improving the same region) replaces tets, and the part's list would name dead ones.
  auto take = [&](CutStepReport& r, const Cutter* from) {
    apply_change(r.change, from);
    ms += r.ms;
    improve_ms += r.ms_improve;
    std::vector<std::vector<TetId>> parts;
    for (Fragment& fr : r.fragments) parts.push_back(std::move(fr.tets));
    handle_fragments(std::move(parts), std::move(r.body.tets));
  };
  // The improvement of blades withdrawn earlier goes on, one slice a frame.
  if (blade_ && blade_->finishing()) {
    CutStepReport r = blade_->finish_more();
    take(r, blade_.get());
  }
  for (const auto& cutter : cutters_)
    if (cutter->finishing()) {
      CutStepReport r = cutter->finish_more();
      take(r, cutter.get());
    }
  for (std::size_t i = 0; i < cutters_.size(); ++i) {
    const SceneCut& c = scene_.cuts[i];
    const auto take_cut = [&](CutStepReport& r) {
      cut_tallies_[i].tets_cut += r.tets_cut;
      cut_tallies_[i].faces_opened += r.cut_faces;
      cut_tallies_[i].parts += r.fragments.size();
      take(r, cutters_[i].get());
    };
    if (!c.path.empty()) {
      if (swept_[i] >= 1 || frame_ < c.from_frame) continue;
      if (bound < 0) bound = max_displacement_bound();
      CutStepReport r = cutters_[i]->advance(path_blade(c, frame_), current, bound);
      take_cut(r);
      if (frame_ >= c.to_frame) {
        swept_[i] = 1;
        CutStepReport fin = cutters_[i]->finish(current);
        take_cut(fin);
      }
      continue;
    }
    const double f = sweep_fraction(c, frame_);
    if (f <= swept_[i]) continue;
    const Vec3 off = f * c.sweep;
    if (bound < 0) bound = max_displacement_bound();
    CutStepReport r = cutters_[i]->advance({c.a + off, c.b + off}, current, bound);
    swept_[i] = f;
    take_cut(r);
    if (f >= 1) {
      CutStepReport fin = cutters_[i]->finish(current);
      take_cut(fin);
    }
  }
  return ms;
}

CutStepReport SceneRunner::advance_blade(const BladeSegment& blade, const CutOptions& options) {
  const bool placing = !blade_ || !blade_->in_cut();
  SceneInput in;
  in.kind = SceneInput::Kind::Blade;
  in.a = blade.a;
  in.b = blade.b;
  if (placing) {
    in.mode = options.mode == CutMode::Remove ? "remove" : "subdivide";
    in.snap = options.snap;
    in.improve = options.improve;
    // What a scene input cannot say: the rest of CutOptions must be the defaults.
    CutOptions said = cut_options(in);
    const CutOptions& o = options;
    replayable_ = replayable_ && o.frozen.empty() && o.finish_improve_work == said.finish_improve_work &&
                  o.improve_budget_ms == said.improve_budget_ms && o.fragment_search_limit == said.fragment_search_limit &&
                  o.improve_options.max_work == said.improve_options.max_work &&
                  (o.finish_improve_slice == 0 || o.finish_improve_slice == kFinishImproveSlice);
  }
  CutStepReport r = blade_step(blade, options);
  record(in);
  return r;
}

// A frame budget is a time: the cut's improvement gets a share of it (0: no budget, the
// improvement bounded by its operation counts alone, reproducibly).
double SceneRunner::improve_time_cap() const {
  return fem_ && scene_.cg.budget_ms > 0 ? kCutImproveShareOfBudget * scene_.cg.budget_ms : 0.0;
}

CutOptions SceneRunner::cut_options(const SceneInput& in) {
  CutOptions o;
  o.mode = in.mode == "remove" ? CutMode::Remove : CutMode::Subdivide;
  o.snap = in.snap;
  o.improve = in.improve;
  return o;
}

CutStepReport SceneRunner::blade_step(const BladeSegment& blade, const CutOptions& given) {
  const auto t0 = std::chrono::steady_clock::now();
  CutStepReport r;
  if (!blade_ || !blade_->in_cut()) {
    CutOptions options = given;
    if (options.finish_improve_slice == 0) options.finish_improve_slice = kFinishImproveSlice;
    // One cutter for every outside cut: its first-contact grid is built once and kept up to
    // date by the changes it is notified of.
    if (!blade_) blade_ = std::make_unique<Cutter>(mesh_, options);
    else blade_->options() = options;
    blade_->start(blade);
  } else {
    r = took_blade_step(blade_->advance(blade, [this](VertexId v) { return position(v); }, max_displacement_bound()));
  }
  outside_ms_ += ms_since(t0);  // an outside step counts against the next frame's budget
  return r;
}

void SceneRunner::record(SceneInput in) {
  in.frame = frame_;
  applied_.push_back(std::move(in));
}

// An outside blade's step reaches the backend and the other cutters, and its detached parts
// follow the fragment policy; the report goes back without them.
CutStepReport SceneRunner::took_blade_step(CutStepReport r) {
  apply_change(r.change, blade_.get());
  total_cut_ms_ += r.ms;
  std::vector<std::vector<TetId>> parts;
  for (Fragment& fr : r.fragments) parts.push_back(std::move(fr.tets));
  r.fragments.clear();
  handle_fragments(std::move(parts), std::move(r.body.tets));
  r.body = Fragment{};
  return r;
}

CutStepReport SceneRunner::finish_blade() {
  if (!blade_ || !blade_->in_cut()) return {};
  const auto t0 = std::chrono::steady_clock::now();
  CutStepReport r = blade_->finish([this](VertexId v) { return position(v); });
  r = took_blade_step(std::move(r));
  outside_ms_ += ms_since(t0);
  record({.kind = SceneInput::Kind::Finish});
  return r;
}

void SceneRunner::set_probe(const std::vector<VertexId>& vertices, const Vec3& displacement) {
  hold_probe(vertices, displacement);
  replayable_ = false;  // a list of vertex ids is not a scene input
}

void SceneRunner::hold_probe(const std::vector<VertexId>& vertices, const Vec3& displacement) {
  free_probe();
  for (VertexId v : vertices)
    if (mesh_.is_alive(v) && !held_by_scene(v)) probe_.push_back(v);
  probe_displacement_ = displacement;
}

void SceneRunner::free_probe() {
  for (VertexId v : probe_) {
    if (!mesh_.is_alive(v)) continue;
    if (fem_) fem_->release(v);
    else springs_->clear_prescribed(v);
  }
  probe_.clear();
}

void SceneRunner::release_probe() {
  const bool held = !probe_.empty();
  free_probe();
  if (held) record({.kind = SceneInput::Kind::Release});
}

std::size_t SceneRunner::grab_probe(const Vec3& point, double radius) {
  const std::vector<VertexId> near = vertices_near(point, radius);
  probe_base_ = Vec3::Zero();
  for (VertexId v : near) probe_base_ += position(v) - mesh_.rest(v);
  if (!near.empty()) probe_base_ /= double(near.size());
  hold_probe(near, probe_base_);
  record({.kind = SceneInput::Kind::Grab, .a = point, .radius = radius});
  return probe_.size();
}

void SceneRunner::move_probe(const Vec3& displacement) {
  if (probe_.empty()) return;
  probe_displacement_ = probe_base_ + displacement;
  record({.kind = SceneInput::Kind::Probe, .a = displacement});
}

void SceneRunner::replay_inputs() {
  const std::vector<SceneInput>& in = scene_.inputs;
  for (; next_input_ < in.size() && in[next_input_].frame <= frame_; ++next_input_) {
    const SceneInput& x = in[next_input_];
    switch (x.kind) {
      case SceneInput::Kind::Blade: advance_blade({x.a, x.b}, cut_options(x)); break;
      case SceneInput::Kind::Finish: finish_blade(); break;
      case SceneInput::Kind::Grab: grab_probe(x.a, x.radius); break;
      case SceneInput::Kind::Probe: move_probe(x.a); break;
      case SceneInput::Kind::Release: release_probe(); break;
    }
  }
}

void SceneRunner::edit(const std::function<std::vector<std::vector<TetId>>(TetMesh&)>& fn) {
  replayable_ = false;  // an arbitrary edit is not a scene input
  const std::vector<std::vector<TetId>> parts = fn(mesh_);
  apply_change(mesh_.take_change(), nullptr);
  handle_fragments(parts);
}

SceneFrame SceneRunner::step() {
  const auto frame_start = std::chrono::steady_clock::now();
  // Outside blade steps taken since the last frame count against this frame's budget; those
  // replayed below run inside the frame and are counted by its clock.
  const double outside = std::exchange(outside_ms_, 0.0);
  const Scene& s = scene_;
  SceneFrame out;
  out.frame = frame_;
  replay_inputs();  // what an outside hand did before this frame, then the scene's blades
  outside_ms_ = 0;  // the replayed steps ran inside this frame's clock
  out.cut_ms = cut_scene_blades(out.cut_improve_ms);
  total_cut_ms_ += out.cut_ms;
  // Loads and probes at this frame, then the outside probe.
  force_.assign(mesh_.vertex_capacity(), Vec3::Zero());
  for (std::size_t i = 0; i < s.loads.size(); ++i) {
    const SceneLoad& l = s.loads[i];
    const double f = l.factor(frame_);
    if (l.kind == SceneLoad::Kind::Force) {
      for (VertexId v : load_vertices_[i]) force_[v.idx()] += f * l.value / double(load_vertices_[i].size());
    } else if (!face_lists_.empty() && !face_lists_[i].empty()) {
      continue;  // quadratic tets: added per face below
    } else if (l.kind == SceneLoad::Kind::Pressure) {
      for (const FaceShare& w : face_shares_[i]) force_[w.vertex.idx()] -= f * l.value.x() * w.area_vector;
    } else if (l.kind == SceneLoad::Kind::Traction) {
      for (const FaceShare& w : face_shares_[i]) force_[w.vertex.idx()] += f * w.area * l.value;
    } else if (l.kind == SceneLoad::Kind::Probe) {
      for (VertexId v : load_vertices_[i]) {
        if (fem_) fem_->prescribe(v, f * l.value);
        else springs_->set_prescribed(v, mesh_.rest(v) + f * l.value);
      }
    }
  }
  for (VertexId v : probe_) {
    if (!mesh_.is_alive(v)) continue;
    if (fem_) fem_->prescribe(v, probe_displacement_);
    else springs_->set_prescribed(v, mesh_.rest(v) + probe_displacement_);
  }
  FrameStats& st = out.stats;
  Eigen::VectorXd& disp = out.displacement;
  if (fem_) {
    fem_->clear_forces();
    for (std::size_t v = 0; v < force_.size(); ++v)
      if (force_[v].squaredNorm() > 0) fem_->set_force(VertexId(std::uint32_t(v)), force_[v]);
    for (std::size_t i = 0; i < face_lists_.size(); ++i) {
      const SceneLoad& l = s.loads[i];
      const double f = l.factor(frame_);
      for (const auto& fc : face_lists_[i]) {
        const Vec3 n = (mesh_.rest(fc[1]) - mesh_.rest(fc[0])).cross(mesh_.rest(fc[2]) - mesh_.rest(fc[0])).normalized();
        fem_->add_face_traction(fc[0], fc[1], fc[2], l.kind == SceneLoad::Kind::Pressure ? Vec3(-f * l.value.x() * n) : Vec3(f * l.value));
      }
    }
    // The frame's cutting so far (an outside blade since the last frame, the scene's blades, the
    // backends' updates, the loads) comes off solver.budget_ms: the budget bounds the frame.
    const double spent = outside + ms_since(frame_start);
    try {
      st = fem_->step(spent);
    } catch (const InvalidArgument& e) {
      fail(s, "fixed", e.what());
    }
    if (st.info == SolveInfo::NotPositiveDefinite || st.info == SolveInfo::NumericalIssue)
      throw Error(s.path + ": frame " + std::to_string(frame_) + ": " + st.message);
    disp = fem_->displacement().head(Eigen::Index(3 * mesh_.vertex_capacity()));
  } else {
    for (std::size_t v = 0; v < force_.size(); ++v)
      if (mesh_.is_alive(VertexId(std::uint32_t(v)))) springs_->set_external_force(VertexId(std::uint32_t(v)), force_[v]);
    const auto t0 = std::chrono::steady_clock::now();
    for (int k = 0; k < s.substeps; ++k) {
      const StepStats ss = springs_->step(s.dt, integrator_);
      st.iterations += ss.cg_iterations;
      st.relative_residual = ss.cg_relative_residual;
    }
    st.solve_ms = st.frame_ms = ms_since(t0);
    out.stable_dt = springs_->stable_time_step();  // cuts make smaller tets, and the bound with them
    disp = Eigen::VectorXd::Zero(Eigen::Index(3 * mesh_.vertex_capacity()));
    const auto& x = springs_->positions();
    for (VertexId v : mesh_.vertices()) disp.segment<3>(3 * v.idx()) = x[v.idx()] - mesh_.rest(v);
  }
  out.max_displacement = max_displacement(disp);
  check_solution(s, frame_, out.max_displacement, st.relative_residual, size_);
  out.inverted = count_inverted(mesh_, disp);
  out.time = dynamic_ ? (frame_ + 1) * s.dt * (s.model == SceneModel::Springs ? s.substeps : 1) : frame_;
  ++frame_;
  return out;
}

}  // namespace incise
