// incise trade's frontier, recommendations and plot against the reference's error bar: errors
// the reference cannot resolve count as equal, so a faster row below the bar leads.
#include <catch2/catch.hpp>

#include <regex>

#include "scene/trade.h"

using namespace incise;

namespace {

TradeRow row(double ms, double error) {
  TradeRow r;
  r.ms_per_frame = ms;
  r.error = error;
  r.model = "fem-linear";
  r.formulation = "standard";
  return r;
}

}  // namespace

TEST_CASE("trade: errors below the reference's error bar are not resolved and stay off the frontier", "[scene][trade]") {
  std::vector<TradeRow> rows{row(1, 0.01), row(10, 0.001), row(30, 0.2), row(40, 0.06)};
  mark_pareto(rows);  // no bar: both of the first two are on the frontier
  CHECK(rows[0].pareto);
  CHECK(rows[1].pareto);
  CHECK_FALSE(rows[2].pareto);
  CHECK_FALSE(rows[3].pareto);
  CHECK(rows[0].resolved);
  CHECK(recommend(rows, {20})[0] == &rows[1]);
  mark_pareto(rows, 0.05);  // the first two below the bar: not resolved, off the frontier
  CHECK_FALSE(rows[0].resolved);
  CHECK_FALSE(rows[1].resolved);
  CHECK_FALSE(rows[0].pareto);
  CHECK_FALSE(rows[1].pareto);
  CHECK(rows[2].pareto);  // the fastest resolved row
  CHECK(rows[3].pareto);  // slower, but more accurate
  CHECK(trade_csv(rows).find(",pareto,resolved\n") != std::string::npos);
  // Recommendations: errors below the bar tie, so the faster one leads.
  CHECK(recommend(rows, {20}, 0.05)[0] == &rows[0]);
  CHECK(recommend(rows, {0.5}, 0.05)[0] == nullptr);
}

TEST_CASE("trade: the plot draws the reference's error bar and keeps every budget line inside", "[scene][trade]") {
  const std::vector<TradeRow> rows{row(20, 0.01), row(80, 0.001)};
  const std::string svg = trade_svg(rows, "t", {2, 16, 33}, 0.005);
  CHECK(svg.find("reference's error bar: below, not resolved") != std::string::npos);
  // The 2 ms line (all rows are slower) lies inside the plot, which starts at x = 80.
  std::smatch m;
  REQUIRE(std::regex_search(svg, m, std::regex("<line x1=\"([0-9.e+-]+)\"[^>]*stroke-dasharray=\"2,4\"/><text[^>]*>2 ms")));
  CHECK(std::stod(m[1].str()) >= 80);
}
