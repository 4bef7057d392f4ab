// The trade plot: error against time per frame on log-log axes, one colour per model, one
// marker per solver kind, the Pareto frontier as a staircase through its points.
#include <algorithm>
#include <cmath>
#include <sstream>

#include "sim/trade.h"

namespace incise {

namespace {

const char* colour(const std::string& model) {
  if (model == "fem-linear") return "#1f77b4";
  if (model == "fem-corotational") return "#d62728";
  return "#2ca02c";
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

std::string trade_svg(const std::vector<TradeRow>& rows, const std::string& title) {
  const double w = 820, h = 560, l = 80, r = 200, t = 50, b = 60;
  const double floor_err = 1e-12, floor_ms = 1e-3;
  auto lx = [&](double ms) { return std::log10(std::max(ms, floor_ms)); };
  auto ly = [&](double e) { return std::log10(std::max(e, floor_err)); };
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const TradeRow& row : rows) {
    x0 = std::min(x0, lx(row.ms_per_frame));
    x1 = std::max(x1, lx(row.ms_per_frame));
    y0 = std::min(y0, ly(row.error));
    y1 = std::max(y1, ly(row.error));
  }
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
    << ") rotate(-90)\" text-anchor=\"middle\">error vs corotational direct (relative)</text>\n";
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
    tip << row.model << " " << row.solver << " " << row.preconditioner << " tol " << row.tolerance << " budget "
        << row.budget_ms << " ms: " << row.ms_per_frame << " ms/frame, error " << row.error;
    const std::string stroke = row.pareto ? " stroke=\"#000\" stroke-width=\"2\"" : "";
    s << "<g fill=\"" << colour(row.model) << "\" fill-opacity=\"0.75\"><title>" << escape(tip.str()) << "</title>";
    if (row.solver == "direct")
      s << "<rect x=\"" << x - 5 << "\" y=\"" << y - 5 << "\" width=\"10\" height=\"10\"" << stroke << "/>";
    else if (row.solver == "cg")
      s << "<circle cx=\"" << x << "\" cy=\"" << y << "\" r=\"" << (row.budget_ms > 0 ? 3.5 : 5) << "\"" << stroke << "/>";
    else
      s << "<polygon points=\"" << x << "," << y - 6 << " " << x - 5 << "," << y + 4 << " " << x + 5 << "," << y + 4
        << "\"" << stroke << "/>";
    s << "</g>\n";
  }
  // Legend.
  double ly0 = t + 10;
  for (const char* m : {"fem-linear", "fem-corotational", "springs"}) {
    s << "<circle cx=\"" << w - r + 20 << "\" cy=\"" << ly0 << "\" r=\"5\" fill=\"" << colour(m) << "\"/><text x=\""
      << w - r + 32 << "\" y=\"" << ly0 + 4 << "\">" << m << "</text>\n";
    ly0 += 20;
  }
  s << "<text x=\"" << w - r + 14 << "\" y=\"" << ly0 + 4 << "\">o CG (small: budgeted)</text>\n";
  s << "<text x=\"" << w - r + 14 << "\" y=\"" << ly0 + 22 << "\">[] direct, ^ springs</text>\n";
  s << "<text x=\"" << w - r + 14 << "\" y=\"" << ly0 + 40 << "\">outlined, dashed: Pareto</text>\n";
  s << "</svg>\n";
  return s.str();
}

}  // namespace incise
