#!/usr/bin/python3
"""Plots the FEM benchmark CSVs (bench_fem_kx, bench_fem_solver, bench_fem_local_update) into
one SVG a person can look at. Plain python3, no matplotlib: the SVG is written by hand.
    /usr/bin/python3 bench/plot_fem.py DIR      -> DIR/fem_benchmarks.svg
Missing CSVs are skipped."""
import csv
import math
import os
import sys

COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2"]


def read(path):
    if not os.path.exists(path):
        return None
    with open(path) as f:
        return list(csv.DictReader(f))


def ticks(lo, hi, log):
    if log:
        a, b = math.floor(math.log10(lo)), math.ceil(math.log10(hi))
        step = max(1, (b - a) // 6)
        return [10.0 ** e for e in range(a, b + 1, step)]
    span = hi - lo or 1.0
    raw = span / 5
    mag = 10 ** math.floor(math.log10(raw))
    step = min((m * mag for m in (1, 2, 5, 10) if m * mag >= raw), default=mag)
    t = math.ceil(lo / step) * step
    out = []
    while t <= hi + 1e-12 * span:
        out.append(t)
        t += step
    return out


def fmt(v):
    if v == 0:
        return "0"
    if abs(v) >= 1e4 or abs(v) < 1e-2:
        return "%.0e" % v
    return ("%g" % round(v, 3))


def panel(out, x0, y0, w, h, title, xlabel, ylabel, series, logx=False, logy=False):
    pts = [(x, y) for _, xs, ys in series for x, y in zip(xs, ys)
           if (not logx or x > 0) and (not logy or y > 0) and math.isfinite(x) and math.isfinite(y)]
    out.append('<text x="%d" y="%d" font-size="13" font-weight="bold">%s</text>' % (x0, y0 - 8, title))
    if not pts:
        out.append('<text x="%d" y="%d" font-size="11">(no data)</text>' % (x0 + 10, y0 + 20))
        return
    xs = [p[0] for p in pts]
    ys = [p[1] for p in pts]
    xlo, xhi, ylo, yhi = min(xs), max(xs), min(ys), max(ys)
    if xlo == xhi:
        xlo, xhi = (xlo / 2, xhi * 2) if logx else (xlo - 1, xhi + 1)
    if ylo == yhi:
        ylo, yhi = (ylo / 2, yhi * 2) if logy else (ylo - 1, yhi + 1)
    if not logy and ylo > 0 and ylo < 0.5 * yhi:
        ylo = 0
    tx = (lambda v: math.log10(v)) if logx else (lambda v: v)
    ty = (lambda v: math.log10(v)) if logy else (lambda v: v)
    X = lambda v: x0 + 50 + (tx(v) - tx(xlo)) / (tx(xhi) - tx(xlo)) * (w - 60)
    Y = lambda v: y0 + h - 35 - (ty(v) - ty(ylo)) / (ty(yhi) - ty(ylo)) * (h - 45)
    out.append('<rect x="%d" y="%d" width="%d" height="%d" fill="none" stroke="#999"/>' % (x0 + 50, y0 + 10 - 10, w - 60, h - 35))
    for t in ticks(xlo, xhi, logx):
        if xlo <= t <= xhi:
            out.append('<line x1="%.1f" y1="%d" x2="%.1f" y2="%d" stroke="#eee"/>' % (X(t), y0, X(t), y0 + h - 35))
            out.append('<text x="%.1f" y="%d" font-size="10" text-anchor="middle">%s</text>' % (X(t), y0 + h - 22, fmt(t)))
    for t in ticks(ylo, yhi, logy):
        if ylo <= t <= yhi:
            out.append('<line x1="%d" y1="%.1f" x2="%d" y2="%.1f" stroke="#eee"/>' % (x0 + 50, Y(t), x0 + w - 10, Y(t)))
            out.append('<text x="%d" y="%.1f" font-size="10" text-anchor="end">%s</text>' % (x0 + 47, Y(t) + 3, fmt(t)))
    out.append('<text x="%d" y="%d" font-size="11" text-anchor="middle">%s</text>' % (x0 + 50 + (w - 60) / 2, y0 + h - 6, xlabel))
    out.append('<text x="%d" y="%d" font-size="11" text-anchor="middle" transform="rotate(-90 %d %d)">%s</text>'
               % (x0 + 12, y0 + (h - 35) / 2, x0 + 12, y0 + (h - 35) / 2, ylabel))
    for i, (name, sx, sy) in enumerate(series):
        c = COLORS[i % len(COLORS)]
        p = [(X(x), Y(y)) for x, y in zip(sx, sy) if (not logx or x > 0) and (not logy or y > 0) and math.isfinite(y)]
        if len(p) > 1:
            out.append('<polyline fill="none" stroke="%s" stroke-width="1.8" points="%s"/>' % (c, " ".join("%.1f,%.1f" % q for q in p)))
        for q in p:
            out.append('<circle cx="%.1f" cy="%.1f" r="2.5" fill="%s"/>' % (q[0], q[1], c))
        out.append('<text x="%d" y="%d" font-size="10" fill="%s">%s</text>' % (x0 + w - 12 - 7 * len(name), y0 + 12 + 12 * i, c, name))


def col(rows, key, cond=lambda r: True):
    return [float(r[key]) for r in rows if cond(r)]


def main():
    d = sys.argv[1] if len(sys.argv) > 1 else "."
    panels = []
    kx = read(os.path.join(d, "fem_kx.csv"))
    if kx:
        s = []
        for th in ("1", "2"):
            sel = lambda r, th=th: r["threads"] == th
            s.append(("matrix-free %s thr" % th, col(kx, "tets", sel), col(kx, "matrix_free_ms", sel)))
            s.append(("assembled %s thr" % th, col(kx, "tets", sel), col(kx, "assembled_ms", sel)))
        panels.append(("K*x time", "tets", "ms", s, True, True))
        panels.append(("K*x: % of STREAM bandwidth bound", "tets", "%", [
            ("matrix-free 1 thr", col(kx, "tets", lambda r: r["threads"] == "1"), col(kx, "mf_pct_bound", lambda r: r["threads"] == "1")),
            ("assembled 1 thr", col(kx, "tets", lambda r: r["threads"] == "1"), col(kx, "assembled_pct_bound", lambda r: r["threads"] == "1"))],
            True, False))
    wc = read(os.path.join(d, "fem_warm_cold.csv"))
    if wc:
        s = [("cold", col(wc, "frame", lambda r: float(r["probe_step_pct"]) == 1.0), col(wc, "cold_iterations", lambda r: float(r["probe_step_pct"]) == 1.0))]
        for pct in sorted({float(r["probe_step_pct"]) for r in wc}, reverse=True):
            sel = lambda r, pct=pct: float(r["probe_step_pct"]) == pct
            s.append(("warm, probe %g%%/frame" % pct, col(wc, "frame", sel), col(wc, "warm_iterations", sel)))
        panels.append(("Warm vs cold start", "frame", "CG iterations", s, False, False))
    cap = read(os.path.join(d, "fem_cap_error.csv"))
    if cap:
        panels.append(("Iteration cap -> error vs direct", "CG iterations", "relative error",
                       [("error", col(cap, "iterations"), col(cap, "relative_error")),
                        ("residual", col(cap, "iterations"), col(cap, "relative_residual"))], False, True))
    bud = read(os.path.join(d, "fem_budget_error.csv"))
    if bud:
        s = []
        for b in sorted({float(r["budget_ms"]) for r in bud}):
            sel = lambda r, b=b: float(r["budget_ms"]) == b
            s.append(("budget %g ms" % b, col(bud, "frame", sel), col(bud, "relative_error", sel)))
        panels.append(("Frame budget: error over frames", "frame", "relative error", s, False, True))
    tol = read(os.path.join(d, "fem_tolerance_error.csv"))
    if tol:
        panels.append(("Tolerance -> error", "tolerance", "relative error vs direct",
                       [("error", col(tol, "tolerance"), col(tol, "relative_error")),
                        ("tolerance", col(tol, "tolerance"), col(tol, "tolerance"))], True, True))
    res = read(os.path.join(d, "fem_resolution.csv"))
    if res:
        panels.append(("Resolution -> error vs Timoshenko", "tets", "tip error", [("linear tets", col(res, "tets"), col(res, "tip_error_vs_timoshenko"))], True, True))
        panels.append(("Resolution -> time", "tets", "ms", [("CG (cold, 1e-8)", col(res, "tets"), col(res, "cg_ms")),
                                                             ("direct LDLT", col(res, "tets"), col(res, "direct_ms"))], True, True))
    cond = read(os.path.join(d, "fem_conditioning.csv"))
    if cond:
        sel = lambda r: r["series"] == "poisson"
        panels.append(("CG iterations vs Poisson ratio", "0.5 - nu", "iterations",
                       [("Jacobi CG", [0.5 - x for x in col(cond, "parameter", sel)], col(cond, "iterations", sel))], True, True))
        sel = lambda r: r["series"] == "quality"
        panels.append(("CG iterations vs worst dihedral", "worst dihedral [deg]", "iterations",
                       [("jittered box", col(cond, "worst_dihedral_deg", sel), col(cond, "iterations", sel))], True, False))
    lu = read(os.path.join(d, "fem_local_update.csv"))
    if lu:
        s = []
        for n in sorted({int(float(r["tets"]) / 1000) for r in lu}):
            pass
        groups = {}
        for r in lu:
            groups.setdefault(r["rebuild_model_ms"], []).append(r)
        for key, rows in groups.items():
            n = float(rows[0]["tets"])
            s.append(("local, %dk tets" % round(n / 1000), col(rows, "edited_tets"), col(rows, "local_ms")))
            s.append(("reassembly, %dk" % round(n / 1000), col(rows, "edited_tets"), col(rows, "reassemble_ms")))
        panels.append(("Local update vs rebuild", "edited tets", "ms", s, True, True))
    cols, w, h = 3, 420, 300
    rows = (len(panels) + cols - 1) // cols
    out = ['<svg xmlns="http://www.w3.org/2000/svg" width="%d" height="%d" font-family="sans-serif">' % (cols * w + 20, rows * h + 50),
           '<rect width="100%" height="100%" fill="white"/>',
           '<text x="10" y="22" font-size="16" font-weight="bold">incise FEM benchmarks (%s)</text>' % os.path.abspath(d)]
    for i, p in enumerate(panels):
        panel(out, 10 + (i % cols) * w, 50 + (i // cols) * h, w - 20, h - 30, *p)
    out.append("</svg>")
    path = os.path.join(d, "fem_benchmarks.svg")
    with open(path, "w") as f:
        f.write("\n".join(out))
    print("wrote", path, "with", len(panels), "panels")


if __name__ == "__main__":
    main()
