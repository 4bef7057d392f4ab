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
#include "scene/trade_reference.h"
#include "sim/fem/fem_model.h"
#include "sim/fem/mixed_solver.h"

namespace incise {

using namespace trade_detail;

namespace {

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
          // The nodal term's shares: the scene's (NaN: unnamed), or a row each.
          std::vector<double> shares{std::nan("")};
          if (v == "nodal" && !opt.spring_nodal_shares.empty()) shares = opt.spring_nodal_shares;
          for (double share : shares)
            for (const std::string& c : opt.spring_connectivity)
              for (const std::string& k : opt.spring_stiffness) {
                if (c == "across-faces" && k != "van-gelder") continue;
                Setting vs = st;
                vs.scene.springs_volume = v;
                vs.scene.springs_stiffness = k;
                vs.scene.springs_connectivity = c;
                std::string name = "volume " + v;
                if (!std::isnan(share)) {
                  vs.scene.springs_nodal_share = share;
                  name += " " + fmt(share);
                }
                // No comma: a CSV field.
                vs.row.formulation = name + (c == "edges" ? "" : " " + c) + (k == "van-gelder" ? "" : " (" + k + ")");
                out.push_back(vs);
              }
        }
        continue;
      }
      for (Formulation f : opt.formulations) {
        Setting fs = st;
        fs.scene.formulation = f;
        fs.row.formulation = std::string(formulation_name(f));
        if (is_quadratic(f)) {
          // Quadratic tets are a reference discretization: solved directly, to tolerance, no barrier.
          fs.scene.method = SolverMethod::Direct;
          fs.scene.cg.budget_ms = 0;
          fs.scene.inversion_barrier = {};
        }
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
          // Quadratic tets take no budget and have no multigrid (scene_parse refuses both).
          if (is_quadratic(base.formulation) && (budget > 0 || pc == Preconditioner::Amg)) continue;
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
  Basis basis;
  prepare(basis, cut_scene, opt, opt.resolutions);
  const Scene& scene = basis.scene;
  TradeResult result;
  result.reference = basis.reference;
  result.coarser = basis.coarser;
  const std::vector<int>& levels = basis.levels;
  const int frames = basis.frames;
  const TetMesh& ref_mesh = basis.ref_mesh();
  const std::vector<Eigen::VectorXd>& ref = basis.ref;
  auto mesh = [&](int level) -> const TetMesh& { return basis.mesh(level, opt.progress); };
  auto probe = [&](int level) -> const Probe& {
    mesh(level);
    return basis.probe(level);
  };

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
  mark_pareto(rows, std::max(result.reference.error_bar, 0.0));
  result.coarser = basis.coarser;  // level -1 is made when its first run needs it
  return result;
}

void mark_pareto(std::vector<TradeRow>& rows, double resolved) {
  for (TradeRow& a : rows) a.resolved = !(a.error < resolved);
  for (TradeRow& a : rows) {
    a.pareto = a.resolved;
    for (const TradeRow& b : rows)
      if (a.pareto && &a != &b && b.resolved && b.ms_per_frame <= a.ms_per_frame && b.error <= a.error &&
          (b.ms_per_frame < a.ms_per_frame || b.error < a.error))
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
