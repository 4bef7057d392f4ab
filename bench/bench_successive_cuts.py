#!/usr/bin/python3
"""Successive cuts: each `incise cut` on the previous one's output (issue 36).

A blade of 160 mm, level above the body, at a random point of the middle of its xy extent
and a random direction, swept down 40-80% of the height in 10 steps; 20 such cuts of the
sample liver by default. Per cut: the tets before and after, the tets of the input the cut
split (`tets_cut`), the net growth per cut tet (growth from the cut, not from re-splitting
earlier pieces, stays flat if it is), the smallest dihedral and the share below 10 degrees
after, and of it the share the surface forces (tets around boundary edges sharper than 10
degrees, where cuts meet at small angles) with the sharpest boundary edge, and the share
across parts thinner than a quarter of the tets' longest edge (layers between two cuts or a cut
and the surface, which only smaller tets would mesh well; `incise quality --json`).

  /usr/bin/python3 bench/bench_successive_cuts.py [--build DIR] [--cuts N] [--seed S] [MESH]

CUT_ARGS (environment) adds options to every `incise cut`, e.g. CUT_ARGS="--finish-work 40000".
"""
import argparse
import json
import math
import os
import random
import subprocess
import sys
import tempfile


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser()
    ap.add_argument("mesh", nargs="?", default=os.path.join(here, "..", "samples", "liver.msh"))
    ap.add_argument("--build", default=os.path.join(here, "..", "build"))
    ap.add_argument("--cuts", type=int, default=20)
    ap.add_argument("--seed", type=int, default=20)
    a = ap.parse_args()
    exe = os.path.join(a.build, "cli", "incise")
    def quality(path):
        return json.loads(subprocess.run([exe, "quality", path, "--json", "--solver-estimate", "formula"],
                                         check=True, capture_output=True, text=True).stdout)

    info = quality(a.mesh)
    lo, hi = info["bounding_box"]["min"], info["bounding_box"]["max"]
    rng = random.Random(a.seed)
    print("cut,tets_before,tets_after,tets_cut,net_growth_per_cut_tet,min_dihedral,below_10deg_pct,"
          "forced_below_10deg_pct,thin_below_10deg_pct,sharpest_boundary_deg,ms_total")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = os.environ.get("KEEP_DIR", tmp)
        prev = a.mesh
        for k in range(1, a.cuts + 1):
            cx = lo[0] + (hi[0] - lo[0]) * rng.uniform(0.3, 0.7)
            cy = lo[1] + (hi[1] - lo[1]) * rng.uniform(0.3, 0.7)
            ang, half = rng.uniform(0, math.pi), 80.0
            z = hi[2] + 5
            p = (cx - half * math.cos(ang), cy - half * math.sin(ang), z)
            q = (cx + half * math.cos(ang), cy + half * math.sin(ang), z)
            depth = (hi[2] - lo[2]) * rng.uniform(0.4, 0.8)
            out, rep = os.path.join(tmp, f"cut{k}.msh"), os.path.join(tmp, f"cut{k}.json")
            r = subprocess.run([exe, "cut", prev, "-o", out, "--blade", *map(str, p + q), "--sweep", "0", "0",
                                str(-depth), "--steps", "10", "--json", rep, "-q", *os.environ.get("CUT_ARGS", "").split()], capture_output=True, text=True)
            if r.returncode:
                sys.exit(r.stderr.strip())
            j = json.load(open(rep))
            qj = quality(out)
            net = j["tets_after"] - j["tets_before"]
            below = 100.0 * qj["elements"]["slivers"] / max(qj["counts"]["tets"], 1)
            forced = 100.0 * qj["elements"]["forced_slivers"] / max(qj["counts"]["tets"], 1)
            thin = 100.0 * qj["elements"]["thin_slivers"] / max(qj["counts"]["tets"], 1)
            sharp = qj["boundary"]["sharpest_edge"]["degrees"] if qj["boundary"]["sharpest_edge"] else 180.0
            print(f"{k},{j['tets_before']},{j['tets_after']},{j['tets_cut']},{net / max(j['tets_cut'], 1):.2f},"
                  f"{j['min_dihedral_after']:.2f},{below:.2f},{forced:.2f},{thin:.2f},{sharp:.2f},{j['ms_total']:.0f}", flush=True)
            prev = out


if __name__ == "__main__":
    main()
