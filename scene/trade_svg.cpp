// The trade plot: error against time per frame on log-log axes, one colour per model and
// formulation, one marker per mesh resolution, the Pareto frontier as a staircase through its
// points, the frame budgets as vertical lines.
#include <algorithm>
#include <cmath>
#include <sstream>

#include "scene/trade.h"

namespace incise {

namespace {

struct Series {
  const char* model;
  const char* formulation;
  const char* colour;
};
constexpr Series kSeries[] = {{"fem-linear", "standard", "#1f77b4"},
                              {"fem-linear", "nodal-averaged", "#17becf"},
                              {"fem-linear", "edge-smoothed", "#393b79"},
                              {"fem-linear", "mixed", "#9467bd"},
                              {"fem-corotational", "standard", "#d62728"},
                              {"fem-corotational", "nodal-averaged", "#ff7f0e"},
                              {"fem-corotational", "edge-smoothed", "#bcbd22"},
                              {"fem-corotational", "mixed", "#8c564b"},
                              {"springs", "-", "#2ca02c"}};

const char* colour(const TradeRow& r) {
  for (const Series& s : kSeries)
    if (r.model == s.model && r.formulation == s.formulation) return s.colour;
  return "#7f7f7f";
}

// Marker per resolution: -1 triangle, 0 circle, 1 square, 2 and finer diamond.
std::string marker(int level, double x, double y, double size, const std::string& extra) {
  std::ostringstream s;
  if (level < 0)
    s << "<polygon points=\"" << x << "," << y - size * 1.2 << " " << x - size << "," << y + size * 0.8 << " " << x + size
      << "," << y + size * 0.8 << "\"" << extra << "/>";
  else if (level == 0)
    s << "<circle cx=\"" << x << "\" cy=\"" << y << "\" r=\"" << size << "\"" << extra << "/>";
  else if (level == 1)
    s << "<rect x=\"" << x - size << "\" y=\"" << y - size << "\" width=\"" << 2 * size << "\" height=\"" << 2 * size
      << "\"" << extra << "/>";
  else
    s << "<polygon points=\"" << x << "," << y - size * 1.3 << " " << x + size * 1.3 << "," << y << " " << x << ","
      << y + size * 1.3 << " " << x - size * 1.3 << "," << y << "\"" << extra << "/>";
  return s.str();
}

std::string escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '<') o += "&lt;";
    else if (c == '>') o += "&gt;";
    else if (c == '&') o += "&amp;";
    else o += c;
  }
  return o;
}

}  // namespace

std::string trade_svg(const std::vector<TradeRow>& rows, const std::string& title, const std::vector<double>& budgets_ms,
                      double resolved) {
  const double w = 900, h = 580, l = 80, r = 280, t = 50, b = 60;
  const double floor_err = 1e-12, floor_ms = 1e-3;
  auto lx = [&](double ms) { return std::log10(std::max(ms, floor_ms)); };
  auto ly = [&](double e) { return std::log10(std::max(e, floor_err)); };
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const TradeRow& row : rows) {
    x0 = std::min(x0, lx(row.ms_per_frame));
    x1 = std::max(x1, lx(row.ms_per_frame));
    for (double budget : budgets_ms) x0 = std::min(x0, lx(budget)), x1 = std::max(x1, lx(budget));  // every line inside
    y0 = std::min(y0, ly(row.error));
    y1 = std::max(y1, ly(row.error));
  }
  if (resolved > 0 && !rows.empty()) y0 = std::min(y0, ly(resolved) - 0.3), y1 = std::max(y1, ly(resolved) + 0.3);
  if (rows.empty()) x0 = y0 = 0, x1 = y1 = 1;
  x0 = std::floor(x0), x1 = std::max(std::ceil(x1), x0 + 1);
  y0 = std::floor(y0), y1 = std::max(std::ceil(y1), y0 + 1);
  auto px = [&](double ms) { return l + (lx(ms) - x0) / (x1 - x0) * (w - l - r); };
  auto py = [&](double e) { return h - b - (ly(e) - y0) / (y1 - y0) * (h - t - b); };

  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << w << "\" height=\"" << h
    << "\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  s << "<text x=\"" << l << "\" y=\"28\" font-size=\"15\">" << escape(title) << "</text>\n";
  // Axes with a tick per decade.
  s << "<rect x=\"" << l << "\" y=\"" << t << "\" width=\"" << w - l - r << "\" height=\"" << h - t - b
    << "\" fill=\"none\" stroke=\"#444\"/>\n";
  for (double d = x0; d <= x1 + 1e-9; d += 1) {
    const double x = px(std::pow(10.0, d));
    s << "<line x1=\"" << x << "\" y1=\"" << t << "\" x2=\"" << x << "\" y2=\"" << h - b
      << "\" stroke=\"#ddd\"/><text x=\"" << x << "\" y=\"" << h - b + 16 << "\" text-anchor=\"middle\">1e" << d
      << "</text>\n";
  }
  for (double d = y0; d <= y1 + 1e-9; d += 1) {
    const double y = py(std::pow(10.0, d));
    s << "<line x1=\"" << l << "\" y1=\"" << y << "\" x2=\"" << w - r << "\" y2=\"" << y
      << "\" stroke=\"#ddd\"/><text x=\"" << l - 6 << "\" y=\"" << y + 4 << "\" text-anchor=\"end\">1e" << d
      << "</text>\n";
  }
  s << "<text x=\"" << (l + w - r) / 2 << "\" y=\"" << h - 18 << "\" text-anchor=\"middle\">time per frame [ms]</text>\n";
  s << "<text transform=\"translate(20," << (t + h - b) / 2
    << ") rotate(-90)\" text-anchor=\"middle\">error vs converged reference (relative L2)</text>\n";
  if (resolved > 0) {  // the reference's error bar: errors below it are not resolved
    const double y = py(resolved);
    s << "<rect x=\"" << l << "\" y=\"" << y << "\" width=\"" << w - l - r << "\" height=\"" << h - b - y
      << "\" fill=\"#f2f2f2\"/><line x1=\"" << l << "\" y1=\"" << y << "\" x2=\"" << w - r << "\" y2=\"" << y
      << "\" stroke=\"#999\"/><text x=\"" << w - r - 4 << "\" y=\"" << y - 4
      << "\" text-anchor=\"end\" fill=\"#555\">reference's error bar: below, not resolved</text>\n";
  }
  for (double budget : budgets_ms) {
    const double x = px(budget);
    s << "<line x1=\"" << x << "\" y1=\"" << t << "\" x2=\"" << x << "\" y2=\"" << h - b
      << "\" stroke=\"#888\" stroke-dasharray=\"2,4\"/><text x=\"" << x + 3 << "\" y=\"" << t + 12 << "\" fill=\"#555\">"
      << budget << " ms</text>\n";
  }
  // Pareto frontier: a staircase through the frontier points in time order.
  std::vector<const TradeRow*> front;
  for (const TradeRow& row : rows)
    if (row.pareto) front.push_back(&row);
  std::sort(front.begin(), front.end(), [](auto* a, auto* c) { return a->ms_per_frame < c->ms_per_frame; });
  if (!front.empty()) {
    s << "<polyline fill=\"none\" stroke=\"#000\" stroke-width=\"1.5\" stroke-dasharray=\"5,3\" points=\"";
    for (std::size_t i = 0; i < front.size(); ++i) {
      if (i) s << px(front[i]->ms_per_frame) << "," << py(front[i - 1]->error) << " ";
      s << px(front[i]->ms_per_frame) << "," << py(front[i]->error) << " ";
    }
    s << "\"/>\n";
  }
  for (const TradeRow& row : rows) {
    const double x = px(row.ms_per_frame), y = py(row.error);
    std::ostringstream tip;
    tip << "level " << row.resolution << " (" << row.tets << " tets) " << row.model << " " << row.formulation << " "
        << row.solver << " " << row.preconditioner << " tol " << row.tolerance << " budget " << row.budget_ms
        << " ms: " << row.ms_per_frame << " ms/frame, error " << row.error << " (" << row.compared << ")";
    const std::string stroke = row.pareto ? " stroke=\"#000\" stroke-width=\"2\"" : "";
    s << "<g fill=\"" << colour(row) << "\" fill-opacity=\"0.75\"><title>" << escape(tip.str()) << "</title>"
      << marker(row.resolution, x, y, row.budget_ms > 0 ? 3.5 : 5, stroke) << "</g>\n";
  }
  // Legend: the series present, then the markers.
  double ly0 = t + 10;
  for (const Series& se : kSeries) {
    bool present = false;
    for (const TradeRow& row : rows) present = present || (row.model == se.model && row.formulation == se.formulation);
    if (!present) continue;
    s << "<circle cx=\"" << w - r + 20 << "\" cy=\"" << ly0 << "\" r=\"5\" fill=\"" << se.colour << "\"/><text x=\""
      << w - r + 32 << "\" y=\"" << ly0 + 4 << "\">" << se.model << (std::string(se.formulation) == "-" ? "" : std::string(" ") + se.formulation)
      << "</text>\n";
    ly0 += 20;
  }
  for (int level : {-1, 0, 1, 2}) {
    bool present = false;
    for (const TradeRow& row : rows) present = present || std::min(row.resolution, 2) == level;
    if (!present) continue;
    s << "<g fill=\"#666\">" << marker(level, w - r + 20, ly0, 5, "") << "</g><text x=\"" << w - r + 32 << "\" y=\""
      << ly0 + 4 << "\">mesh level " << level << (level == 0 ? " (the scene's)" : level < 0 ? " (coarser)" : " (refined)")
      << "</text>\n";
    ly0 += 20;
  }
  s << "<text x=\"" << w - r + 14 << "\" y=\"" << ly0 + 4 << "\">small: CG with a frame budget</text>\n";
  s << "<text x=\"" << w - r + 14 << "\" y=\"" << ly0 + 22 << "\">outlined, dashed: Pareto</text>\n";
  s << "</svg>\n";
  return s.str();
}

}  // namespace incise
