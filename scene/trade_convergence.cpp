// incise trade --convergence (scene/trade.h): per model and formulation, the error at each mesh
// level against trade's reference, and the observed order.
#include <cmath>
#include <ostream>

#include "mesh/errors.h"
#include "scene/trade.h"
#include "scene/trade_reference.h"

namespace incise {

using namespace trade_detail;

ConvergenceResult run_convergence(const Scene& cut_scene, const TradeOptions& opt) {
  std::vector<int> levels = opt.resolutions;
  if (levels.empty()) {
    // 0, 1, 2 while the reference one level above the finest stays within max_reference_tets.
    Scene uncut = cut_scene;
    uncut.cuts.clear();
    const double tets = double(body_at(uncut, 0, nullptr).num_tets());
    levels = {0};
    for (int l = 1; l <= 2; ++l)
      if (tets * std::pow(8.0, l + 1) <= double(opt.max_reference_tets)) levels.push_back(l);
    if (levels.size() < 2) levels.insert(levels.begin(), -1);  // an order needs two levels
  }
  Basis b;
  prepare(b, cut_scene, opt, levels);
  ConvergenceResult out;
  out.reference = b.reference;
  out.coarser = b.coarser;
  for (SceneModel model : opt.models) {
    if (model == SceneModel::Springs) continue;
    for (Formulation f : opt.formulations) {
      ConvergenceRow row;
      row.model = model_name(model);
      row.formulation = std::string(formulation_name(f));
      for (int level : b.levels) {
        Scene rs = b.scene;
        rs.model = model;
        rs.formulation = f;
        rs.method = SolverMethod::Direct;
        rs.integrator = "static";
        rs.cg.budget_ms = 0;
        if (is_quadratic(f)) rs.inversion_barrier = {};
        const TetMesh& m = b.mesh(level, opt.progress);
        const Probe& p = b.probe(level);
        double err = 0, overshoot = 0;
        SceneRunOptions ro;
        ro.frames = b.frames;
        ro.mesh = &m;
        ro.on_frame = [&](int fr, const Eigen::VectorXd& d, const FrameStats&) {
          const Eigen::VectorXd r = sample(b.ref_mesh(), p, b.ref.at(std::size_t(fr)));
          const Errors e = compare(d, r);
          err = std::max(err, e.l2);
          double mu = 0, mr = 0;
          for (Eigen::Index i = 0; i + 2 < std::min(d.size(), r.size()); i += 3)
            mu = std::max(mu, d.segment<3>(i).norm()), mr = std::max(mr, r.segment<3>(i).norm());
          overshoot = mr > 0 ? mu / mr - 1 : 0;
        };
        try {
          run_scene(rs, ro);
        } catch (const Error& e) {
          throw Error("trade --convergence: level " + std::to_string(level) + " " + row.model + " " + row.formulation + ": " +
                      e.what());
        }
        row.levels.push_back(level);
        row.tets.push_back(m.num_tets());
        row.errors.push_back(err);
        row.max_displacement_errors.push_back(overshoot);
        if (opt.progress)
          *opt.progress << "trade: convergence: level " << level << " (" << m.num_tets() << " tets) " << row.model << " "
                        << row.formulation << ": error " << fmt(err) << "\n";
      }
      // The mesh size h as (tets)^(-1/3): a uniform refinement halves it (log2 of the error
      // ratio), a coarsened level -1 is measured by what it really has.
      for (std::size_t k = 0; k + 1 < row.errors.size(); ++k)
        row.orders.push_back(row.errors[k + 1] > 0 && row.tets[k + 1] > row.tets[k]
                                 ? std::log(row.errors[k] / row.errors[k + 1]) /
                                       std::log(std::cbrt(double(row.tets[k + 1]) / double(row.tets[k])))
                                 : std::nan(""));
      out.rows.push_back(std::move(row));
    }
  }
  out.coarser = b.coarser;
  return out;
}

}  // namespace incise
