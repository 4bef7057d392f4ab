#include "scene/run_scene.h"

#include <algorithm>
#include <iomanip>
#include <optional>
#include <ostream>
#include <sstream>

#include "mesh/errors.h"
#include "scene/scene_output.h"
#include "scene/scene_runner.h"

namespace incise {

namespace {

// incise is unit-agnostic: the mesh, the moduli, the densities and g must be in one system.
// A mix (SI materials on a mesh in millimetres) shows in the scale of the sag gravity implies,
// rho g L^2 / E for the softest material on a body of size L: far past the body's size, or a
// vanishing share of it (docs/scene.md#units).
std::string unit_check(const Scene& s, const TetMesh& mesh) {
  Vec3 g = Vec3::Zero();
  for (const SceneLoad& l : s.loads)
    if (l.kind == SceneLoad::Kind::Gravity) g += l.value;
  if (g.norm() == 0 || mesh.num_vertices() == 0) return {};
  Vec3 lo = Vec3::Constant(1e300), hi = -lo;
  for (VertexId v : mesh.vertices()) {
    lo = lo.cwiseMin(mesh.rest(v));
    hi = hi.cwiseMax(mesh.rest(v));
  }
  const double size = (hi - lo).maxCoeff();
  std::vector<Material> ms;
  if (s.materials.has_default()) ms.push_back(s.materials.fallback());
  for (const auto& [label, m] : s.materials.by_label()) ms.push_back(m);
  if (ms.empty()) ms.push_back(Material{});
  double sag = 0;
  for (const Material& m : ms) sag = std::max(sag, m.density * g.norm() * size * size / m.young);
  const double ratio = sag / size;
  if (!(size > 0) || (ratio <= 10 && ratio >= 1e-9)) return {};
  std::ostringstream w;
  w << "gravity " << g.norm() << " on a body " << size << " across with E " << ms[0].young << " and density "
    << ms[0].density << " implies a sag of the order of " << sag << " (rho g L^2 / E), " << ratio
    << " times the body's size: are the mesh, the moduli, the densities and g in one unit system? (m, Pa, kg/m^3, "
    << "m/s^2; or mm, MPa, t/mm^3, mm/s^2: docs/scene.md#units)";
  return w.str();
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
  sum.total_cut_ms = runner.total_cut_ms();
  sum.fragments_handled = runner.fragments_handled();
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
    if (c.to_frame >= sum.frames || runner.tets_cut()[i] > 0) continue;
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
