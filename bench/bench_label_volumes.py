#!/usr/bin/python3
"""Label volumes through cuts, CutOptions::exact_volumes (the default) against without it (docs/cut.md#label-volumes).

Per seed, N random straight cuts (a blade level above the body through a random point of the
middle of its xy extent, in a random direction, swept down 40-90% of the height in 10 steps),
once with exact_volumes off and once with it on (the default): the largest change of one
label's volume relative to the body's, the body's own change, the tets after, the smallest
dihedral angle and the share of tets below 10 degrees.

  /usr/bin/python3 bench/bench_label_volumes.py [--build DIR] [--cuts N] [--seeds S ...] [MESH]

MESH: the sample liver by default; the docs' organ is `incise tetra samples/liver.inr.gz -o
organ.vtu --size 2%`.
"""
import argparse
import math
import os
import random
import sys

import numpy as np


def label_volumes(m):
    p, t, lab = m.points, m.tets, m.labels
    a, b, c, d = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]], p[t[:, 3]]
    v = np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6
    return {int(l): v[lab == l].sum() for l in np.unique(lab)}, v.sum()


def quality(m):
    x = m.points[m.tets]
    faces = [(1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2)]
    n = [np.cross(x[:, f[1]] - x[:, f[0]], x[:, f[2]] - x[:, f[0]]) for f in faces]
    n = [k / np.linalg.norm(k, axis=1)[:, None] for k in n]
    ang = [180 - np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", n[i], n[j]), -1, 1)))
           for i in range(4) for j in range(i + 1, 4)]
    worst = np.min(np.stack(ang, 1), 1)
    return worst.min(), 100 * (worst < 10).mean()


def run(incise, path, cuts, seed, exact):
    m = incise.read(path)
    v0, b0 = label_volumes(m)
    p = m.points
    lo, hi = p.min(0), p.max(0)
    ext = hi - lo
    cutter = incise.Cutter(m, exact_volumes=exact)
    rng = random.Random(seed)
    for _ in range(cuts):
        c = lo + ext * np.array([rng.uniform(.3, .7), rng.uniform(.3, .7), 1.05])
        ang = rng.uniform(0, math.pi)
        d = np.array([math.cos(ang), math.sin(ang), 0])
        a, b = c - 0.8 * ext.max() * d, c + 0.8 * ext.max() * d
        step = np.array([0, 0, -ext[2] * rng.uniform(.4, .9)]) / 10
        cutter.start(a, b)
        for s in range(1, 11):
            cutter.advance(a + s * step, b + s * step)
        cutter.finish()
    v1, b1 = label_volumes(m)
    worst = max(abs(v1[l] - v0[l]) for l in v0) / b0
    md, below = quality(m)
    return worst, abs(b1 - b0) / b0, len(m.tets), md, below


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser()
    ap.add_argument("mesh", nargs="?", default=os.path.join(here, "..", "samples", "liver.msh"))
    ap.add_argument("--build", default=os.path.join(here, "..", "build"))
    ap.add_argument("--cuts", type=int, default=8)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    a = ap.parse_args()
    sys.path.insert(0, os.path.join(a.build, "python"))
    import incise
    print(f"# {a.mesh}: {a.cuts} random cuts per seed; label change and body change relative to the body")
    print("seed,mode,label_change,body_change,tets_after,min_dihedral,below_10deg_pct")
    for seed in a.seeds:
        for exact in (False, True):
            w, b, n, md, below = run(incise, a.mesh, a.cuts, seed, exact)
            print(f"{seed},{'exact (default)' if exact else 'not exact'},{w:.2e},{b:.2e},{n},{md:.3f},{below:.2f}", flush=True)


if __name__ == "__main__":
    main()
