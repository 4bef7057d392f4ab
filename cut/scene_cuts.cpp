#include "cut/scene_cuts.h"

#include <algorithm>
#include <memory>

#include "cut/cutter.h"

namespace incise {

namespace {
// Fraction of the sweep done when `frame` is solved.
double sweep_fraction(const SceneCut& c, int frame) {
  if (frame < c.from_frame) return 0;
  if (c.to_frame <= c.from_frame || frame >= c.to_frame) return 1;
  return double(frame - c.from_frame + 1) / double(c.to_frame - c.from_frame + 1);
}
}  // namespace

SceneCutHook make_scene_cut_hook(const Scene& scene) {
  struct State {
    std::vector<std::unique_ptr<Cutter>> cutters;
    std::vector<double> done;  // fraction cut so far
  };
  auto st = std::make_shared<State>();
  st->cutters.resize(scene.cuts.size());
  st->done.assign(scene.cuts.size(), 0.0);
  const std::vector<SceneCut> cuts = scene.cuts;
  return [st, cuts](int frame, TetMesh& mesh, const std::function<Vec3(VertexId)>& current,
                    const std::function<double()>& max_displacement_of,
                    const std::function<void(const TopologyChange&)>& apply) {
    SceneCutResult res;
    double max_displacement = -1;  // measured once, in the first frame step that needs it
    // Every cutter (and its first-contact grid, O(mesh)) is made before the first frame's
    // cuts, as setup; afterwards each step's change is passed to the other cutters, so no
    // grid goes stale (only a fragment removal by the scene makes them rebuild).
    if (!cuts.empty() && !st->cutters[0])
      for (std::size_t i = 0; i < cuts.size(); ++i) {
        CutOptions o;
        o.mode = cuts[i].mode == "remove" ? CutMode::Remove : CutMode::Subdivide;
        o.snap = cuts[i].snap;
        o.improve = cuts[i].improve;
        st->cutters[i] = std::make_unique<Cutter>(mesh, o);
        st->cutters[i]->start({cuts[i].a, cuts[i].b});
      }
    for (std::size_t i = 0; i < cuts.size(); ++i) {
      const SceneCut& c = cuts[i];
      const double f = sweep_fraction(c, frame);
      if (f <= st->done[i]) continue;
      const Vec3 off = f * c.sweep;
      if (max_displacement < 0) max_displacement = max_displacement_of();
      CutStepReport r = st->cutters[i]->advance({c.a + off, c.b + off}, current, max_displacement);
      st->done[i] = f;
      for (std::size_t j = 0; j < cuts.size(); ++j)
        if (j != i) st->cutters[j]->notify(r.change);
      apply(r.change);
      res.ms += r.ms;
      for (Fragment& fr : r.fragments) res.fragments.push_back(std::move(fr.tets));
      if (f >= 1) {  // the sweep is done: the blade is withdrawn, its front released
        CutStepReport fin = st->cutters[i]->finish(current);
        if (!fin.change.empty()) {
          for (std::size_t j = 0; j < cuts.size(); ++j)
            if (j != i) st->cutters[j]->notify(fin.change);
          apply(fin.change);
        }
        res.ms += fin.ms;
        for (Fragment& fr : fin.fragments) res.fragments.push_back(std::move(fr.tets));
      }
    }
    return res;
  };
}

SceneRunSummary run_scene_with_cuts(const Scene& scene, SceneRunOptions options) {
  if (!scene.cuts.empty()) options.cut_hook = make_scene_cut_hook(scene);
  return run_scene(scene, options);
}

}  // namespace incise
