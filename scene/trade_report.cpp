// What incise trade writes: the CSV, the JSON and the closing summary (frontier and one
// recommendation per frame budget).
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include <nlohmann/json.hpp>

#include "scene/trade.h"

namespace incise {

namespace {

std::string setting(const TradeRow& r) {
  std::ostringstream s;
  s << "level " << r.resolution << " (" << r.tets << " tets) " << r.model;
  if (r.formulation != "-") s << " " << r.formulation;
  s << " " << r.solver;
  if (!r.preconditioner.empty()) s << " " << r.preconditioner << " tolerance " << r.tolerance;
  if (r.budget_ms > 0) s << " budget " << r.budget_ms << " ms";
  return s.str();
}

}  // namespace

std::string trade_csv(const std::vector<TradeRow>& rows) {
  std::ostringstream s;
  s << "resolution,tets,model,formulation,solver,preconditioner,tolerance,budget_ms,ms_per_frame,iterations,error,"
       "max_displacement_error,compared,settle_frames,settle_ms,dt,settled,frames_not_converged,pareto,resolved\n";
  s << std::setprecision(8);
  for (const TradeRow& r : rows)
    s << r.resolution << "," << r.tets << "," << r.model << "," << r.formulation << "," << r.solver << "," << r.preconditioner
      << "," << r.tolerance << "," << r.budget_ms << "," << r.ms_per_frame << "," << r.iterations << "," << r.error << ","
      << r.max_displacement_error << "," << r.compared << "," << r.settle_frames << "," << r.settle_ms << "," << r.dt << ","
      << (r.settled ? 1 : 0) << "," << r.frames_not_converged << "," << (r.pareto ? 1 : 0) << "," << (r.resolved ? 1 : 0)
      << "\n";
  return s.str();
}

std::string trade_json(const TradeResult& res, const std::vector<double>& budgets_ms) {
  using nlohmann::json;
  json rows = json::array();
  for (const TradeRow& r : res.rows)
    rows.push_back({{"resolution", r.resolution}, {"tets", r.tets}, {"model", r.model}, {"formulation", r.formulation},
                    {"solver", r.solver}, {"preconditioner", r.preconditioner}, {"tolerance", r.tolerance},
                    {"budget_ms", r.budget_ms}, {"ms_per_frame", r.ms_per_frame}, {"iterations", r.iterations},
                    {"error", r.error}, {"max_displacement_error", r.max_displacement_error}, {"compared", r.compared},
                    {"settle_frames", r.settle_frames}, {"settle_ms", r.settle_ms}, {"dt", r.dt}, {"settled", r.settled},
                    {"frames_not_converged", r.frames_not_converged}, {"pareto", r.pareto}, {"resolved", r.resolved}});
  json recs = json::array();
  const auto best = recommend(res.rows, budgets_ms, std::max(res.reference.error_bar, 0.0));
  for (std::size_t i = 0; i < budgets_ms.size(); ++i)
    recs.push_back({{"frame_budget_ms", budgets_ms[i]},
                    {"row", best[i] ? json(std::size_t(best[i] - res.rows.data())) : json(nullptr)},
                    {"setting", best[i] ? json(setting(*best[i])) : json(nullptr)}});
  json out = {{"reference",
               {{"level", res.reference.level}, {"tets", res.reference.tets}, {"formulation", res.reference.formulation}, {"method", res.reference.method},
                {"seconds", res.reference.seconds},
                {"change_from_coarser", res.reference.change >= 0 ? json(res.reference.change) : json(nullptr)},
                {"error_bar", res.reference.error_bar >= 0 ? json(res.reference.error_bar) : json(nullptr)},
                {"error_bar_order", res.reference.order}}},
              {"coarser", res.coarser.empty() ? json(nullptr) : json(res.coarser)},
              {"rows", rows},
              {"recommendations", recs}};
  return out.dump(2) + "\n";
}

std::string convergence_table(const ConvergenceResult& res) {
  std::ostringstream s;
  s << std::setprecision(3);
  s << "convergence against a level-" << res.reference.level << " reference (" << res.reference.tets
    << " tets, fem-corotational " << res.reference.formulation << ", " << res.reference.method;
  if (res.reference.error_bar >= 0) s << "; error bar " << res.reference.error_bar;
  s << "): relative L2 error of displacement per level, observed order between levels\n";
  if (!res.coarser.empty()) s << "level -1: " << res.coarser << "\n";
  std::vector<int> levels;
  for (const ConvergenceRow& r : res.rows)
    for (int l : r.levels)
      if (std::find(levels.begin(), levels.end(), l) == levels.end()) levels.push_back(l);
  std::sort(levels.begin(), levels.end());
  s << std::left << std::setw(38) << "model formulation";
  for (int l : levels) s << std::setw(12) << ("level " + std::to_string(l));
  for (std::size_t k = 0; k + 1 < levels.size(); ++k)
    s << std::setw(10) << ("p " + std::to_string(levels[k]) + "-" + std::to_string(levels[k + 1]));
  s << "\n";
  for (const ConvergenceRow& r : res.rows) {
    s << std::setw(38) << (r.model + " " + r.formulation);
    for (double e : r.errors) {
      std::ostringstream c;
      c << std::setprecision(3) << e << (res.reference.error_bar >= 0 && e < res.reference.error_bar ? "*" : "");
      s << std::setw(12) << c.str();
    }
    for (double p : r.orders) {
      std::ostringstream c;
      c << std::fixed << std::setprecision(2) << p;
      s << std::setw(10) << (std::isnan(p) ? std::string("-") : c.str());
    }
    s << "\n";
  }
  if (res.reference.error_bar >= 0) s << "(*: below the reference's error bar, not resolved)\n";
  s << "largest displacement against the reference's, signed (+: overshoot)\n";
  for (const ConvergenceRow& r : res.rows) {
    s << std::setw(38) << (r.model + " " + r.formulation);
    for (double e : r.max_displacement_errors) {
      std::ostringstream c;
      c << std::showpos << std::setprecision(3) << e;
      s << std::setw(12) << c.str();
    }
    s << "\n";
  }
  return s.str();
}

std::string trade_summary(const TradeResult& res, const std::vector<double>& budgets_ms) {
  std::ostringstream s;
  s << std::setprecision(3);
  s << "trade: " << res.rows.size() << " runs against a level-" << res.reference.level << " reference ("
    << res.reference.tets << " tets, fem-corotational " << res.reference.formulation << ", " << res.reference.method;
  if (res.reference.change >= 0)
    s << "; it moves by " << res.reference.change << " from one level coarser: error bar " << res.reference.error_bar
      << " (Richardson, order " << res.reference.order << ")";
  s << ")\n";
  std::size_t unresolved = 0;
  for (const TradeRow& r : res.rows) unresolved += !r.resolved;
  if (unresolved) s << unresolved << " rows have errors below the error bar: not resolved, kept off the frontier\n";
  if (!res.coarser.empty()) s << "level -1: " << res.coarser << "\n";
  s << "Pareto frontier (fastest first):\n";
  std::vector<const TradeRow*> front;
  for (const TradeRow& r : res.rows)
    if (r.pareto) front.push_back(&r);
  std::sort(front.begin(), front.end(), [](auto* a, auto* b) { return a->ms_per_frame < b->ms_per_frame; });
  s << "  " << std::left << std::setw(10) << "ms/frame" << std::setw(10) << "error" << "setting\n";
  for (const TradeRow* r : front)
    s << "  " << std::setw(10) << r->ms_per_frame << std::setw(10) << r->error << setting(*r)
      << (r->compared == "at-rest" ? " (at rest)" : "") << "\n";
  const auto best = recommend(res.rows, budgets_ms, std::max(res.reference.error_bar, 0.0));
  for (std::size_t i = 0; i < budgets_ms.size(); ++i) {
    s << "for a " << budgets_ms[i] << " ms frame: ";
    if (!best[i]) s << "nothing measured fits\n";
    else s << setting(*best[i]) << ": " << best[i]->ms_per_frame << " ms/frame, error " << best[i]->error << "\n";
  }
  return s.str();
}

}  // namespace incise
