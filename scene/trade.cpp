#include "scene/trade.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <map>
#include <memory>
#include <ostream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "mesh/memory_limit.h"
#include "mesh/point_locator.h"
#include "mesh/refine.h"
#include "quality/coarsen.h"
#include "sim/fem_model.h"
#include "sim/mixed_solver.h"

namespace incise {

namespace {

// Memory of the reference solve per tet (the mesh, the mixed model and the exact Cholesky
// factor of its displacement block, whose fill grows about as the cube root of the size):
// docs/solver.md#picking-settings-for-a-scene-incise-trade.
double reference_bytes_per_tet(double tets) { return 1500 * std::max(1.0, std::cbrt(tets / 3.3e5)); }

const char* model_name(SceneModel m) {
  switch (m) {
    case SceneModel::FemLinear: return "fem-linear";
    case SceneModel::FemCorotational: return "fem-corotational";
    case SceneModel::Springs: return "springs";
  }
  return "?";
}

std::string fmt(double v) {
  std::ostringstream s;
  s << std::setprecision(4) << v;
  return s.str();
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The scene's body at mesh level `level` (see TradeOptions::resolutions), compacted; `how`
// (level -1) says how the coarser mesh was made.
TetMesh body_at(const Scene& s, int level, std::string* how) {
  if (level < -1) throw InvalidArgument("trade: resolutions below -1 are not supported");
  TetMesh m;
  if (level < 0) {
    if (!s.generator.empty()) {
      auto half = [](int n) { return std::max(1, n / 2); };
      if (how) *how = "the " + s.generator + " generator with half the cells";
      if (s.generator == "ellipsoid") m = generate_scene_mesh(s, {half(s.gen_resolution), 0, 0});
      else m = generate_scene_mesh(s, {half(s.gen_cells[0]), half(s.gen_cells[1]), half(s.gen_cells[2])});
      m.compact();
      return m;
    }
    // A file: nothing regenerates it coarser, so contract its edges to about twice their
    // length (quality/coarsen.h: same labels, tags and body within a bounded distance).
    m = load_scene_mesh(s);
    m.compact();
    const CoarsenReport r = coarsen(m);
    m.discard_change();
    m.compact();
    if (how) {
      std::ostringstream t;
      t << std::setprecision(3) << std::filesystem::path(s.mesh_file).filename().string()
        << " coarsened by edge contraction: " << r.tets_before << " -> " << r.tets_after << " tets, mean edge "
        << r.mean_edge_before << " -> " << r.mean_edge_after << ", surface within " << r.max_deviation;
      *how = t.str();
    }
    return m;
  }
  m = load_scene_mesh(s);  // its file (relative to the scene) or its generator, as run_scene reads it
  m.compact();
  for (int k = 0; k < level; ++k) m = refine_uniform(m);
  m.discard_change();
  return m;
}

// A reference solution read at another mesh's vertices.
struct Probe {
  std::vector<PointLocation> at;  // by vertex slot of the run's mesh (invalid tet: dead slot)
};

Probe locate(const TetMesh& run, const PointLocator& loc) {
  Probe p;
  p.at.resize(run.vertex_capacity(), PointLocation{TetId(), {0, 0, 0, 0}, 0});
  for (VertexId v : run.vertices()) p.at[v.idx()] = loc.locate(run.rest(v));
  return p;
}

// The reference displacement at the run's vertices (3 per vertex slot).
Eigen::VectorXd sample(const TetMesh& ref, const Probe& p, const Eigen::VectorXd& u_ref) {
  Eigen::VectorXd out = Eigen::VectorXd::Zero(Eigen::Index(3 * p.at.size()));
  for (std::size_t v = 0; v < p.at.size(); ++v)
    if (p.at[v].tet.is_valid()) PointLocator::interpolate(ref, p.at[v], u_ref.data(), 3, out.data() + 3 * v);
  return out;
}

struct Errors {
  double l2 = 0, max_disp = 0;
};

Errors compare(const Eigen::VectorXd& u, const Eigen::VectorXd& ref) {
  const Eigen::Index n = std::min(u.size(), ref.size());
  const double norm = ref.head(n).norm(), diff = (u.head(n) - ref.head(n)).norm();
  double mu = 0, mr = 0;
  for (Eigen::Index i = 0; i + 2 < n; i += 3) {
    mu = std::max(mu, u.segment<3>(i).norm());
    mr = std::max(mr, ref.segment<3>(i).norm());
  }
  return {norm > 0 ? diff / norm : diff, mr > 0 ? std::abs(mu - mr) / mr : std::abs(mu - mr)};
}

struct Setting {
  Scene scene;
  TradeRow row;
  bool dynamic = false;
};

// Discretization rows, then solver rows (see trade.h).
std::vector<Setting> grid(const Scene& base, const TradeOptions& opt, const std::vector<int>& levels) {
  std::vector<Setting> out;
  const bool base_dynamic = base.integrator == "implicit-euler";
  for (int level : levels)
    for (SceneModel model : opt.models) {
      Setting st{base, {}, model == SceneModel::Springs || base_dynamic};
      st.scene.model = model;
      st.row.resolution = level;
      st.row.model = model_name(model);
      if (model == SceneModel::Springs) {
        st.scene.integrator = "implicit-euler";
        st.scene.method = SolverMethod::Cg;
        st.scene.formulation = Formulation::Standard;
        st.row.solver = "implicit-euler";
        st.row.tolerance = st.scene.cg.tolerance;
        for (const std::string& v : opt.spring_volumes) {
          Setting vs = st;
          vs.scene.springs_volume = v;
          vs.row.formulation = "volume " + v;
          out.push_back(vs);
        }
        continue;
      }
      for (Formulation f : opt.formulations) {
        Setting fs = st;
        fs.scene.formulation = f;
        fs.row.formulation = std::string(formulation_name(f));
        fs.row.solver = fs.scene.method == SolverMethod::Direct ? "direct" : "cg";
        if (fs.row.solver == "cg") {
          fs.row.preconditioner = std::string(to_string(fs.scene.cg.preconditioner));
          fs.row.tolerance = fs.scene.cg.tolerance;
          fs.row.budget_ms = fs.scene.cg.budget_ms;
        }
        if (fs.dynamic) fs.row.solver = "implicit-euler " + fs.row.solver;
        out.push_back(fs);
      }
    }
  for (SceneModel model : opt.models) {
    if (model == SceneModel::Springs) continue;
    Setting st{base, {}, base_dynamic};
    st.scene.model = model;
    st.row.model = model_name(model);
    st.row.formulation = std::string(formulation_name(base.formulation));
    if (opt.direct) {
      Setting d = st;
      d.scene.method = SolverMethod::Direct;
      d.row.solver = base_dynamic ? "implicit-euler direct" : "direct";
      out.push_back(d);
    }
    for (Preconditioner pc : opt.preconditioners)
      for (double tol : opt.tolerances)
        for (double budget : opt.budgets_ms) {
          Setting c = st;
          c.scene.method = SolverMethod::Cg;
          c.scene.cg.preconditioner = pc;
          c.scene.cg.tolerance = tol;
          c.scene.cg.budget_ms = budget;
          c.scene.cg.max_iterations = std::max(c.scene.cg.max_iterations, 20000);
          c.row.solver = base_dynamic ? "implicit-euler cg" : "cg";
          c.row.preconditioner = std::string(to_string(pc));
          c.row.tolerance = tol;
          c.row.budget_ms = budget;
          out.push_back(c);
        }
  }
  // Drop exact repeats (a discretization row at level 0 with the scene's formulation is also a
  // solver row when the scene's solver is in the grid).
  std::vector<Setting> unique;
  for (Setting& s : out) {
    bool seen = false;
    for (const Setting& u : unique)
      seen = seen || (u.row.resolution == s.row.resolution && u.row.model == s.row.model && u.row.formulation == s.row.formulation &&
                      u.row.solver == s.row.solver && u.row.preconditioner == s.row.preconditioner &&
                      u.row.tolerance == s.row.tolerance && u.row.budget_ms == s.row.budget_ms);
    if (!seen) unique.push_back(std::move(s));
  }
  return unique;
}

// The slowest time scale of the body under the scene's loads: the Rayleigh quotient
// omega^2 = u.K u / u.M u of the reference's final displacement (close to the first mode's
// shape under a static load), with the deviatoric stiffness (defined at any Poisson's ratio;
// lambda only raises omega, so the estimate errs towards a longer time step). Returns 0 for a
// zero displacement.
double slowest_omega(const TetMesh& mesh, const Scene& s, const Eigen::VectorXd& u) {
  const FemModel k(mesh, MixedMaterials(s.materials).deviatoric_table(), FemKind::Linear);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(k.rows()), ku;
  x.head(std::min(x.size(), u.size())) = u.head(std::min(x.size(), u.size()));
  k.multiply(x, ku);
  const double um = x.dot(k.lumped_mass().cwiseProduct(x));
  return um > 0 ? std::sqrt(std::max(0.0, x.dot(ku)) / um) : 0;
}

// Dynamic runs are compared at rest with the reference's last frame: its loads are held from
// that frame on (a ramp that goes on past it stops there, at the value it has there; before
// it, the same ramp). Without this, a `--frames` shorter than a ramp compared springs loaded
// the whole way with a reference loaded part of it (docs/solver.md, *Like with like*).
void hold_loads_at(Scene& s, int frame) {
  for (SceneLoad& l : s.loads) {
    if (l.to_frame <= frame) continue;
    l.value *= l.factor(frame);
    l.to_frame = std::max(frame, l.from_frame);
  }
}

// The last frame any load ramps in: dynamic runs hold the loads after it and settle.
int last_ramp_frame(const Scene& s) {
  int f = 0;
  for (const SceneLoad& l : s.loads) f = std::max(f, l.to_frame);
  return f;
}

}  // namespace

namespace {

// A grid spread over processes: every rank's rows (with their grid indices) to rank 0, which
// puts them back in the grid's order; the other ranks keep none.
void gather_rows(const TradeOptions& opt, const std::vector<std::size_t>& indices, std::vector<TradeRow>& rows) {
  nlohmann::json mine = nlohmann::json::array();
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const TradeRow& r = rows[k];
    mine.push_back({indices[k], r.resolution, r.tets, r.model, r.formulation, r.solver, r.preconditioner, r.tolerance,
                    r.budget_ms, r.ms_per_frame, r.iterations, r.error, r.max_displacement_error, r.compared,
                    r.settle_frames, r.settle_ms, r.dt, r.settled, r.frames_not_converged});
  }
  const std::vector<std::string> all = opt.gather(mine.dump());
  std::vector<std::pair<std::size_t, TradeRow>> indexed;
  for (const std::string& text : all)
    for (const auto& j : nlohmann::json::parse(text)) {
      TradeRow r;
      std::size_t i = 0;
      j.at(0).get_to(i);
      j.at(1).get_to(r.resolution);
      j.at(2).get_to(r.tets);
      j.at(3).get_to(r.model);
      j.at(4).get_to(r.formulation);
      j.at(5).get_to(r.solver);
      j.at(6).get_to(r.preconditioner);
      j.at(7).get_to(r.tolerance);
      j.at(8).get_to(r.budget_ms);
      j.at(9).get_to(r.ms_per_frame);
      j.at(10).get_to(r.iterations);
      j.at(11).get_to(r.error);
      j.at(12).get_to(r.max_displacement_error);
      j.at(13).get_to(r.compared);
      j.at(14).get_to(r.settle_frames);
      j.at(15).get_to(r.settle_ms);
      j.at(16).get_to(r.dt);
      j.at(17).get_to(r.settled);
      j.at(18).get_to(r.frames_not_converged);
      indexed.emplace_back(i, r);
    }
  std::sort(indexed.begin(), indexed.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  rows.clear();
  for (auto& [i, r] : indexed) rows.push_back(std::move(r));
}

}  // namespace

TradeResult run_trade(const Scene& cut_scene, const TradeOptions& opt) {
  // Meshes of different resolutions cut by one blade give different bodies, so there is no
  // shared reference through a cut: settings are compared on the uncut body, and it is said.
  Scene scene = cut_scene;
  if (!scene.cuts.empty()) {
    if (opt.progress)
      *opt.progress << "trade: the scene's " << scene.cuts.size()
                    << " cut(s) are left out: settings are compared on the uncut body\n";
    scene.cuts.clear();
  }
  TradeResult result;
  std::map<int, std::unique_ptr<TetMesh>> meshes;
  auto mesh = [&](int level) -> const TetMesh& {
    auto& m = meshes[level];
    if (!m) {
      m = std::make_unique<TetMesh>(body_at(scene, level, level < 0 ? &result.coarser : nullptr));
      if (level < 0 && opt.progress) *opt.progress << "trade: level -1: " << result.coarser << "\n";
    }
    return *m;
  };
  std::vector<int> levels = opt.resolutions;
  if (levels.empty()) {
    // A coarser level (generated with half the cells, or the file's mesh coarsened), the
    // scene's, and a refined one when its reference (64x the scene's tets) stays within what a
    // direct solve does in seconds.
    levels.push_back(-1);
    levels.push_back(0);
    if (64 * mesh(0).num_tets() <= opt.max_reference_tets) levels.push_back(1);
  }
  std::sort(levels.begin(), levels.end());
  levels.erase(std::unique(levels.begin(), levels.end()), levels.end());
  const int ref_level = opt.reference_level >= 0 ? opt.reference_level : levels.back() + 1;
  if (ref_level <= levels.back())
    throw InvalidArgument("trade: the reference level (" + std::to_string(ref_level) +
                          ") must be above the finest resolution (" + std::to_string(levels.back()) + ")");
  {
    // The reference's size before it is built: each level splits every tet into 8.
    const double tets = double(mesh(0).num_tets()) * std::pow(8.0, ref_level);
    refuse_past_memory("trade: the reference at level " + std::to_string(ref_level), tets * reference_bytes_per_tet(tets),
                       std::to_string(static_cast<long long>(tets)) + " tets", "use a lower --reference-level");
  }
  const int frames = opt.frames >= 0 ? opt.frames : scene.frames;


  // ---- the reference, and the same one level coarser for its error bar ------------------
  const Formulation best = Formulation::Mixed;
  auto solve_reference = [&](int level) {
    Scene rs = scene;
    rs.model = SceneModel::FemCorotational;
    rs.formulation = best;
    // Direct (SparseLU on the saddle point) up to direct_reference_tets; above, its fill makes
    // a frame take tens of seconds, and MINRES with the exact Cholesky factor of the
    // displacement block to a relative residual of 1e-10 gives the same answer to that digit.
    if (mesh(level).num_tets() <= opt.direct_reference_tets) {
      rs.method = SolverMethod::Direct;
    } else {
      rs.method = SolverMethod::Cg;
      rs.cg.preconditioner = Preconditioner::Cholesky;
      rs.cg.tolerance = 1e-10;
      rs.cg.budget_ms = 0;
      rs.cg.max_iterations = 100000;
    }
    rs.integrator = "static";
    std::vector<Eigen::VectorXd> u;
    SceneRunOptions ro;
    ro.frames = frames;
    ro.mesh = &mesh(level);
    ro.on_frame = [&](int, const Eigen::VectorXd& d, const FrameStats&) { u.push_back(d); };
    run_scene(rs, ro);
    return u;
  };
  const TetMesh& ref_mesh = mesh(ref_level);
  if (opt.progress)
    *opt.progress << "trade: reference: level " << ref_level << " (" << ref_mesh.num_tets() << " tets), fem-corotational "
                  << formulation_name(best) << ", "
                  << (ref_mesh.num_tets() <= opt.direct_reference_tets ? "direct" : "MINRES to 1e-10 with the exact factor")
                  << ", " << frames << " frames\n";
  auto t0 = std::chrono::steady_clock::now();
  const std::vector<Eigen::VectorXd> ref = solve_reference(ref_level);
  result.reference = {ref_level, ref_mesh.num_tets(), std::string(formulation_name(best)),
                      ref_mesh.num_tets() <= opt.direct_reference_tets ? "direct" : "minres 1e-10", seconds_since(t0), -1};
  const PointLocator locator(ref_mesh);
  std::map<int, Probe> probes;
  auto probe = [&](int level) -> const Probe& {
    auto it = probes.find(level);
    if (it == probes.end()) it = probes.emplace(level, locate(mesh(level), locator)).first;
    return it->second;
  };
  if (ref_level >= 1) {
    const std::vector<Eigen::VectorXd> coarser = solve_reference(ref_level - 1);
    const TetMesh& cm = mesh(ref_level - 1);
    const Probe& at_scene = probe(0);
    // Both read at the scene mesh's vertices: the coarser one through its own locator.
    const PointLocator cl(cm);
    const Probe at_scene_coarse = locate(mesh(0), cl);
    double change = 0;
    for (std::size_t f = 0; f < ref.size() && f < coarser.size(); ++f)
      change = std::max(change, compare(sample(cm, at_scene_coarse, coarser[f]), sample(ref_mesh, at_scene, ref[f])).l2);
    result.reference.change = change;
  }
  if (opt.progress) {
    *opt.progress << "trade: reference took " << fmt(result.reference.seconds) << " s";
    if (result.reference.change >= 0)
      *opt.progress << "; it differs from level " << ref_level - 1 << " by " << fmt(result.reference.change)
                    << " (relative L2): errors below that are not resolved";
    *opt.progress << "\n";
  }

  // ---- the grid ---------------------------------------------------------------------------
  std::vector<Setting> settings = grid(scene, opt, levels);
  std::vector<TradeRow>& rows = result.rows;
  for (Setting& st : settings)
    if (st.dynamic) hold_loads_at(st.scene, frames - 1);
  const int ramp_end = std::min(last_ramp_frame(scene), frames - 1);
  double spent = 0;
  // Seconds per run measured so far, per level: what is left is estimated from the runs of its
  // own level, else from the nearest measured level scaled by the tet count (a level splits
  // every tet into eight).
  std::map<int, std::pair<double, int>> pace;  // level -> (seconds, runs)
  auto seconds_left = [&](std::size_t from) {
    double left = 0;
    for (std::size_t k = from; k < settings.size(); ++k) {
      const int level = settings[k].row.resolution;
      double best = -1;
      int gap = 1 << 30;
      for (const auto& [l, sr] : pace)
        if (std::abs(l - level) < gap) gap = std::abs(l - level), best = sr.first / sr.second * std::pow(8.0, level - l);
      left += std::max(best, 0.0);
    }
    return left;
  };
  const bool spread = opt.ranks > 1 && opt.gather;
  std::vector<std::size_t> played_here;  // the grid indices of this process's rows
  for (std::size_t i = 0; i < settings.size(); ++i) {
    if (spread && int(i % std::size_t(opt.ranks)) != opt.rank) continue;
    played_here.push_back(i);
    Setting& st = settings[i];
    TradeRow& r = st.row;
    const TetMesh& m = mesh(r.resolution);
    r.tets = m.num_tets();
    const Probe& p = probe(r.resolution);
    double ms = 0, iterations = 0, max_move = 0, max_u = 0;
    int played = 0, calm = 0;
    Eigen::VectorXd last;
    SceneRunOptions ro;
    ro.mesh = &m;
    ro.frames = st.dynamic ? std::max(opt.max_settle_frames, ramp_end + 4) : frames;
    if (st.dynamic) {
      // At the scene's own step a soft body rings for thousands of frames (implicit Euler damps
      // a mode by 1/sqrt(1 + (omega dt)^2) a step): settle with a step of at least 1/omega of
      // the slowest mode, which damps it by 0.7 a step and reaches the same rest state.
      const double omega = slowest_omega(m, st.scene, sample(ref_mesh, p, ref.back()));
      if (omega > 0) st.scene.dt = std::max(st.scene.dt, 1 / omega);
      r.dt = st.scene.dt;
    }
    ro.on_frame = [&](int f, const Eigen::VectorXd& d, const FrameStats& s) {
      ms += s.frame_ms;
      iterations += s.iterations;
      r.frames_not_converged += s.info != SolveInfo::Success;
      ++played;
      if (st.dynamic) {
        max_move = last.size() == d.size() ? (d - last).cwiseAbs().maxCoeff() : 1e300;
        max_u = d.cwiseAbs().maxCoeff();
        last = d;
        return;
      }
      const Errors e = compare(d, sample(ref_mesh, p, ref.at(std::size_t(f))));
      r.error = std::max(r.error, e.l2);
      r.max_displacement_error = std::max(r.max_displacement_error, e.max_disp);
    };
    ro.stop = [&](int f) {
      if (!st.dynamic || f < ramp_end) return false;
      calm = max_move <= opt.settle_tolerance * max_u ? calm + 1 : 0;
      return calm >= 3;
    };
    const auto t_run = std::chrono::steady_clock::now();
    try {
      run_scene(st.scene, ro);
    } catch (const Error& e) {
      throw Error(std::string("trade: level ") + std::to_string(r.resolution) + " " + r.model + " " + r.formulation + " " +
                  r.solver + " " + r.preconditioner + " tolerance " + fmt(r.tolerance) + " budget " + fmt(r.budget_ms) +
                  ": " + e.what());
    }
    const double run_s = seconds_since(t_run);
    spent += run_s;
    pace[r.resolution].first += run_s;
    ++pace[r.resolution].second;
    r.ms_per_frame = played ? ms / played : 0;
    r.iterations = played ? iterations / played : 0;
    if (st.dynamic) {
      r.compared = "at-rest";
      r.settle_frames = played;
      r.settle_ms = ms;
      r.settled = calm >= 3;
      const Errors e = compare(last, sample(ref_mesh, p, ref.back()));
      r.error = e.l2;
      r.max_displacement_error = e.max_disp;
    }
    if (opt.progress) {
      if (i == 0)
        *opt.progress << "trade: " << settings.size() << " runs; the estimate of the time left follows each (from "
                      << "the runs measured so far, 8x a level up)\n";
      const int bar = int(20.0 * double(i + 1) / double(settings.size()));
      *opt.progress << "trade: [" << std::string(std::size_t(bar), '#') << std::string(std::size_t(20 - bar), '.') << "] "
                    << i + 1 << "/" << settings.size() << " level " << r.resolution << " " << r.model << " "
                    << r.formulation << " " << r.solver << (r.preconditioner.empty() ? "" : " " + r.preconditioner)
                    << " tol " << fmt(r.tolerance) << " budget " << fmt(r.budget_ms) << " ms: " << fmt(r.ms_per_frame)
                    << " ms/frame, error " << fmt(r.error)
                    << (st.dynamic ? " at rest after " + std::to_string(r.settle_frames) + " frames" +
                                         (r.settled ? "" : " (not settled)")
                                   : "")
                    << "; about " << fmt(seconds_left(i + 1)) << " s left\n";
    }
    rows.push_back(r);
  }
  if (spread) gather_rows(opt, played_here, rows);
  mark_pareto(rows, std::max(result.reference.change, 0.0));
  return result;
}

void mark_pareto(std::vector<TradeRow>& rows, double resolved) {
  auto err = [&](const TradeRow& r) { return std::max(r.error, resolved); };
  for (TradeRow& a : rows) {
    a.pareto = true;
    for (const TradeRow& b : rows)
      if (&a != &b && b.ms_per_frame <= a.ms_per_frame && err(b) <= err(a) &&
          (b.ms_per_frame < a.ms_per_frame || err(b) < err(a)))
        a.pareto = false;
  }
}

std::vector<const TradeRow*> recommend(const std::vector<TradeRow>& rows, const std::vector<double>& budgets_ms,
                                       double resolved) {
  auto err = [&](const TradeRow& r) { return std::max(r.error, resolved); };
  std::vector<const TradeRow*> out;
  for (double b : budgets_ms) {
    const TradeRow* best = nullptr;
    for (const TradeRow& r : rows)
      if (r.ms_per_frame <= b &&
          (!best || err(r) < err(*best) || (err(r) == err(*best) && r.ms_per_frame < best->ms_per_frame)))
        best = &r;
    out.push_back(best);
  }
  return out;
}

}  // namespace incise
