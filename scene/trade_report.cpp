// What incise trade writes: the CSV, the JSON and the closing summary (frontier and one
// recommendation per frame budget).
#include <algorithm>
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
       "max_displacement_error,compared,settle_frames,settle_ms,dt,settled,frames_not_converged,pareto\n";
  s << std::setprecision(8);
  for (const TradeRow& r : rows)
    s << r.resolution << "," << r.tets << "," << r.model << "," << r.formulation << "," << r.solver << "," << r.preconditioner
      << "," << r.tolerance << "," << r.budget_ms << "," << r.ms_per_frame << "," << r.iterations << "," << r.error << ","
      << r.max_displacement_error << "," << r.compared << "," << r.settle_frames << "," << r.settle_ms << "," << r.dt << ","
      << (r.settled ? 1 : 0) << "," << r.frames_not_converged << "," << (r.pareto ? 1 : 0) << "\n";
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
                    {"frames_not_converged", r.frames_not_converged}, {"pareto", r.pareto}});
  json recs = json::array();
  const auto best = recommend(res.rows, budgets_ms, std::max(res.reference.change, 0.0));
  for (std::size_t i = 0; i < budgets_ms.size(); ++i)
    recs.push_back({{"frame_budget_ms", budgets_ms[i]},
                    {"row", best[i] ? json(std::size_t(best[i] - res.rows.data())) : json(nullptr)},
                    {"setting", best[i] ? json(setting(*best[i])) : json(nullptr)}});
  json out = {{"reference",
               {{"level", res.reference.level}, {"tets", res.reference.tets}, {"formulation", res.reference.formulation}, {"method", res.reference.method},
                {"seconds", res.reference.seconds},
                {"change_from_coarser", res.reference.change >= 0 ? json(res.reference.change) : json(nullptr)}}},
              {"coarser", res.coarser.empty() ? json(nullptr) : json(res.coarser)},
              {"rows", rows},
              {"recommendations", recs}};
  return out.dump(2) + "\n";
}

std::string trade_summary(const TradeResult& res, const std::vector<double>& budgets_ms) {
  std::ostringstream s;
  s << std::setprecision(3);
  s << "trade: " << res.rows.size() << " runs against a level-" << res.reference.level << " reference ("
    << res.reference.tets << " tets, fem-corotational " << res.reference.formulation << ", " << res.reference.method;
  if (res.reference.change >= 0) s << "; it moves by " << res.reference.change << " from one level coarser";
  s << ")\n";
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
  const auto best = recommend(res.rows, budgets_ms, std::max(res.reference.change, 0.0));
  for (std::size_t i = 0; i < budgets_ms.size(); ++i) {
    s << "for a " << budgets_ms[i] << " ms frame: ";
    if (!best[i]) s << "nothing measured fits\n";
    else s << setting(*best[i]) << ": " << best[i]->ms_per_frame << " ms/frame, error " << best[i]->error << "\n";
  }
  return s.str();
}

}  // namespace incise
