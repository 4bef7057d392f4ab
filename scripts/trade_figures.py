#!/usr/bin/python3
"""Prints one `incise trade --json` run as the README gives it (scripts/trade-figures.sh).

usage: trade_figures.py TRADE.json COMMAND SECONDS
"""
import json
import sys


def main():
    path, command, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
    j = json.load(open(path))
    rows, ref = j["rows"], j["reference"]
    print(f"`{command}`: {len(rows)} runs in {seconds / 60:.1f} min ({seconds:.0f} s) on this machine; "
          f"the reference is level {ref['level']} ({ref['tets']:,} tets, {ref['formulation']} corotational, "
          f"{ref['method']}, {ref['seconds']:.1f} s) and moves by {ref['change_from_coarser']:.3f} from one level "
          f"coarser: its error bar (Richardson, order {ref['error_bar_order']:g}) is {ref['error_bar']:.4f}; "
          f"errors below it (marked *) are not resolved and kept off the Pareto frontier.")
    if j.get("coarser"):
        print(f"Level -1: {j['coarser']}.")
    print()
    # The scene's solver at each level: CG with the Cholesky factor to 1e-6, no budget.
    fems = [r for r in rows if r["model"] != "springs" and r["solver"] == "cg" and r["preconditioner"] == "cholesky"
            and r["tolerance"] == 1e-6 and r["budget_ms"] == 0]
    forms = sorted({r["formulation"] for r in fems}, key=["standard", "nodal-averaged", "mixed", "edge-smoothed",
                                                            "mixed-edge-smoothed", "quadratic",
                                                            "mixed-quadratic"].index)
    print("Relative L2 error (ms per frame), CG with the Cholesky factor to 1e-6:")
    print()
    print("| model | level (tets) | " + " | ".join(forms) + " |")
    print("|---|---|" + "---|" * len(forms))
    for model in ["fem-corotational", "fem-linear"]:
        for level in sorted({r["resolution"] for r in fems}):
            cell = {r["formulation"]: r for r in fems if r["model"] == model and r["resolution"] == level}
            if not cell:
                continue
            tets = next(iter(cell.values()))["tets"]
            print(f"| {model} | {level} ({tets:,}) | " +
                  " | ".join(f"{cell[f]['error']:.3f}{'' if cell[f].get('resolved', True) else '*'} "
                             f"({cell[f]['ms_per_frame']:.1f})" if f in cell else "-"
                             for f in forms) + " |")
    print()
    springs = [r for r in rows if r["model"] == "springs"]
    if springs:
        print("Springs at rest: " + ", ".join(f"{r['formulation']} level {r['resolution']} {r['error']:.3f} "
                                             f"({r['ms_per_frame']:.1f} ms)"
                                             for r in sorted(springs, key=lambda r: (r["formulation"], r["resolution"])))
              + ".")
    for rec in j["recommendations"]:
        if rec.get("row", -1) < 0:
            print(f"For a {rec['frame_budget_ms']:g} ms frame: nothing fits.")
            continue
        r = rows[rec["row"]]
        print(f"For a {rec['frame_budget_ms']:g} ms frame: {rec['setting']}: {r['ms_per_frame']:.1f} ms/frame, "
              f"error {r['error']:.3f}.")
    print()


if __name__ == "__main__":
    main()
