#include "scene/run_scene.h"

#include <algorithm>
#include <iomanip>
#include <optional>
#include <ostream>
#include <sstream>

#include "mesh/errors.h"
#include "mesh/rest_bounds.h"
#include "scene/scene_output.h"
#include "scene/scene_runner.h"

namespace incise {

namespace {

double body_size(const TetMesh& mesh) { return rest_bounds(mesh).size().maxCoeff(); }

Vec3 gravity(const Scene& s) {
  Vec3 g = Vec3::Zero();
  for (const SceneLoad& l : s.loads)
    if (l.kind == SceneLoad::Kind::Gravity) g += l.value;
  return g;
}

// The scene's materials with the keys that name them in messages.
std::vector<std::pair<std::string, Material>> named_materials(const Scene& s) {
  std::vector<std::pair<std::string, Material>> ms;
  if (s.materials.has_default()) ms.emplace_back("materials[\"*\"]", s.materials.fallback());
  for (const auto& [label, m] : s.materials.by_label()) ms.emplace_back("materials[\"" + std::to_string(label) + "\"]", m);
  if (ms.empty()) ms.emplace_back("the default material", Material{});
  return ms;
}

// incise is unit-agnostic: the mesh, the moduli, the densities and g must be in one system.
// A mix (SI materials on a mesh in millimetres) shows in the scale of the sag gravity implies,
// rho g L^2 / E for the softest material on a body of size L: far past the body's size, or a
// vanishing share of it (docs/scene.md#units).
std::string unit_check(const Scene& s, const TetMesh& mesh) {
  const Vec3 g = gravity(s);
  const double size = body_size(mesh);
  if (g.norm() == 0 || !(size > 0)) return {};
  const auto ms = named_materials(s);
  double sag = 0;
  for (const auto& [key, m] : ms) sag = std::max(sag, m.density * g.norm() * size * size / m.young);
  const double ratio = sag / size;
  if (ratio <= 10 && ratio >= 1e-9) return {};
  std::ostringstream w;
  w << "gravity " << g.norm() << " on a body " << size << " across with E " << ms[0].second.young << " and density "
    << ms[0].second.density << " implies a sag of the order of " << sag << " (rho g L^2 / E), " << ratio
    << " times the body's size: are the mesh, the moduli, the densities and g in one unit system? (m, Pa, kg/m^3, "
    << "m/s^2; or mm, MPa, t/mm^3, mm/s^2: docs/scene.md#units)";
  return w.str();
}

// A scene that states its units ("units": "mm" or "m") gets the ranges of a body, a tissue and
// the earth's gravity in them checked: one warning per value outside, naming its key. The
// ranges are wide (a cell to a torso; 10 Pa to 100 GPa; 100 to 25,000 kg/m^3; g within 10x
// the earth's): they catch a number in the other system, not an unusual tissue.
std::vector<std::string> stated_unit_checks(const Scene& s, const TetMesh& mesh) {
  std::vector<std::string> out;
  if (s.units.empty()) return out;
  const bool mm = s.units == "mm";
  struct Range {
    const char* what;
    double lo, hi;
    const char* unit;
    const char* meaning;
  };
  const Range size_r = mm ? Range{"the body", 1, 3000, "mm", "1 mm to 3 m"} : Range{"the body", 1e-3, 3, "m", "1 mm to 3 m"};
  const Range young_r = mm ? Range{"young", 1e-5, 1e5, "MPa", "10 Pa to 100 GPa"} : Range{"young", 10, 1e11, "Pa", "10 Pa to 100 GPa"};
  const Range density_r = mm ? Range{"density", 1e-10, 2.5e-8, "t/mm^3", "100 to 25,000 kg/m^3"}
                             : Range{"density", 100, 25000, "kg/m^3", "100 to 25,000 kg/m^3"};
  const Range g_r = mm ? Range{"g", 981, 98100, "mm/s^2", "within 10x the earth's 9810 mm/s^2"}
                       : Range{"g", 0.981, 98.1, "m/s^2", "within 10x the earth's 9.81 m/s^2"};
  auto check = [&](const std::string& key, double v, const Range& r) {
    if (v >= r.lo && v <= r.hi) return;
    std::ostringstream w;
    w << "units \"" << s.units << "\": " << key << " is " << v << " " << r.unit << ", outside " << r.lo << ".." << r.hi << " "
      << r.unit << " (" << r.meaning << "): is it in " << (mm ? "SI (m, Pa, kg/m^3, m/s^2)" : "mm, MPa, t/mm^3, mm/s^2")
      << "? (docs/scene.md#units)";
    out.push_back(w.str());
  };
  check("the body's size (the mesh's largest extent)", body_size(mesh), size_r);
  const Vec3 g = gravity(s);
  const bool dynamic = !s.integrator.empty() && s.integrator != "static";
  for (const auto& [key, m] : named_materials(s)) {
    check(key + ".young", m.young, young_r);
    if (g.norm() > 0 || dynamic || s.model == SceneModel::Springs) check(key + ".density", m.density, density_r);
  }
  if (g.norm() > 0) check("gravity's g", g.norm(), g_r);
  return out;
}

}  // namespace

SceneRunSummary run_scene(const Scene& s, const SceneRunOptions& opt) {
  // Everything the scene says is checked (boxes, constraints) before anything is written.
  SceneRunner runner(s, opt.mesh);
  const int frames = opt.frames >= 0 ? opt.frames : s.frames;
  std::optional<SceneOutput> out;
  if (!opt.out_dir.empty()) out.emplace(s, opt.out_dir);

  SceneRunSummary sum;
  // Standard tets lock: at tissue's Poisson's ratios they are far too stiff (figures: README,
  // bench_fem_locking; docs/solver.md, formulations).
  if (s.model != SceneModel::Springs && s.formulation == Formulation::Standard) {
    double nu = s.materials.has_default() ? s.materials.fallback().poisson : 0;
    for (const auto& [label, m] : s.materials.by_label()) nu = std::max(nu, m.poisson);
    if (nu >= 0.45) {
      std::ostringstream w;
      w << "standard tets at Poisson's ratio " << nu << " lock (they come out far too stiff, the more the closer to 0.5): "
        << "\"formulation\": \"nodal-averaged\" does not (docs/solver.md, formulations)";
      sum.warnings.push_back(w.str());
    }
  }
  sum.vertices = runner.mesh().num_vertices();
  sum.tets = runner.mesh().num_tets();
  for (std::string& w : stated_unit_checks(s, runner.mesh())) sum.warnings.push_back(std::move(w));
  const std::string units = unit_check(s, runner.mesh());
  if (!units.empty()) sum.warnings.push_back(units);
  std::vector<double> frame_ms;  // the solver's frames, for the warning below
  auto finish = [&] {
    if (!out) return;
    for (std::string& f : out->finish()) sum.files.push_back(std::move(f));
  };
  try {
    for (int frame = 0; frame < frames; ++frame) {
      if (opt.before_frame) opt.before_frame(runner);
      const SceneFrame f = runner.step();
      const FrameStats& st = f.stats;
      if (opt.on_frame) opt.on_frame(frame, f.displacement, st);
      const bool converged = st.info == SolveInfo::Success;
      sum.total_iterations += st.iterations;
      sum.total_solve_ms += st.solve_ms;
      sum.frames_budget_exhausted += st.budget_exhausted;
      sum.frames_not_converged += !converged;
      sum.max_displacement = f.max_displacement;
      sum.max_inverted = std::max(sum.max_inverted, f.inverted);
      sum.frames_with_inverted += f.inverted > 0;
      if (f.stable_dt > 0) {
        if (sum.frames == 0) sum.first_stable_dt = f.stable_dt;
        sum.min_stable_dt = sum.min_stable_dt > 0 ? std::min(sum.min_stable_dt, f.stable_dt) : f.stable_dt;
      }
      if (frame > 0) frame_ms.push_back(st.frame_ms);  // frame 0 builds the solver
      ++sum.frames;
      if (out) {
        const std::string vtu = out->add(runner, f, frame % s.output_every == 0 || frame == frames - 1);
        if (!vtu.empty()) sum.files.push_back(vtu);
      }
      if (opt.progress) {
        // Numbered like the files and stats.csv (frame_0000.vtu is frame 0).
        *opt.progress << "simulate: frame " << frame << " (0.." << frames - 1 << "): " << st.iterations << " iterations, residual "
                      << st.relative_residual << ", " << std::fixed << std::setprecision(2) << st.solve_ms << " ms"
                      << std::defaultfloat << std::setprecision(6) << (st.budget_exhausted ? ", budget exhausted" : "")
                      << (!converged && !st.budget_exhausted && runner.fem() ? ", NOT CONVERGED" : "") << "\n";
      }
      if (opt.stop && opt.stop(frame)) break;
    }
  } catch (const Error& e) {
    finish();  // keep the series and stats of the frames that were computed
    // A run that blew up under mixed units: the likely reason goes with the error.
    if (!units.empty()) throw Error(std::string(e.what()) + "; " + units);
    throw;
  } catch (...) {
    finish();
    throw;
  }
  finish();
  // The last frame's stable step from its fastest mode: a report, so a state it cannot read (not
  // finite) is a warning, not a failed run whose frames were all written.
  if (SpringModel* sp = runner.springs(); sp && sum.frames > 0) {
    try {
      sum.estimated_stable_dt = sp->estimated_stable_time_step();
    } catch (const Error& e) {
      sum.warnings.push_back(std::string("springs: no stable step estimated at the last frame: ") + e.what());
    }
  }
  sum.total_cut_ms = runner.total_cut_ms();
  sum.fragments_handled = runner.fragments_handled();
  for (const SceneRunner::CutTally& c : runner.cut_tallies()) sum.cuts.push_back({c.tets_cut, c.faces_opened, c.parts});
  sum.vertices = runner.mesh().num_vertices();  // after the cuts
  sum.tets = runner.mesh().num_tets();
  // Not interactive: say so, and what picks settings for a frame budget.
  if (frame_ms.size() >= 2) {
    std::nth_element(frame_ms.begin(), frame_ms.begin() + frame_ms.size() / 2, frame_ms.end());
    const double median = frame_ms[frame_ms.size() / 2];
    if (opt.slow_frame_ms > 0 && median > opt.slow_frame_ms) {
      std::ostringstream w;
      w << "a frame took " << std::fixed << std::setprecision(0) << median << " ms (median): not interactive; "
        << "`incise trade " << s.path << "` measures the settings that fit a frame budget (docs/solver.md)";
      sum.warnings.push_back(w.str());
    }
  }
  // A blade acts on the deformed shape: one that passed beside or above the body (it sagged,
  // moved) cut nothing, which the frames alone do not show.
  for (std::size_t i = 0; i < s.cuts.size(); ++i) {
    const SceneCut& c = s.cuts[i];
    if (c.to_frame >= sum.frames || runner.cut_tallies()[i].tets_cut > 0) continue;
    Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
    for (VertexId v : runner.mesh().vertices()) {
      lo = lo.cwiseMin(runner.position(v));
      hi = hi.cwiseMax(runner.position(v));
    }
    std::ostringstream w;
    w << "cuts[" << i << "] (frames " << c.from_frame << "-" << c.to_frame << ") cut nothing: its blade never met the body, "
      << "whose deformed shape spans (" << lo.x() << ", " << lo.y() << ", " << lo.z() << ") to (" << hi.x() << ", " << hi.y()
      << ", " << hi.z() << ") at the last frame";
    sum.warnings.push_back(w.str());
  }
  return sum;
}

}  // namespace incise
