#include "scene/run_scene.h"

#include <algorithm>
#include <iomanip>
#include <optional>
#include <ostream>
#include <sstream>

#include "scene/scene_output.h"
#include "scene/scene_runner.h"

namespace incise {

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
  } catch (...) {
    finish();  // keep the series and stats of the frames that were computed
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
