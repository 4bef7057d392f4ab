#!/usr/bin/python3
"""Mesh improvement benchmark: incise improve vs Mmg (mmg3d -optim -nosurf) and Stellar.

Every tool improves the same input mesh; every output is measured the same way, with
`incise quality --json` (tets, worst dihedral angles, smallest radius ratio). Prints a
markdown table with the tet count as a ratio to the input's, measured in this run.

  /usr/bin/python3 bench/bench_improve_peers.py [--build DIR] [--mmg PATH] [--stellar PATH]
                                               [--time-limit S] [mesh ...]

Inputs: any tet mesh incise reads; by default the sample liver prepared without improvement
(`incise prepare samples/liver.inr.gz --no-improve`) and, when the build extracted CGAL's data
set, its elephant and fandisk meshed by `incise tetra` (CGAL engine, 3% size). The peers are
built outside the project from their public source (docs/improve.md, "Peers"); a tool not
given or not found is skipped with a note. Stellar runs twice: with its built-in defaults
(vertex insertion on) and with a config file that turns insertion off.
"""
import argparse
import os
import shutil
import sys
import tempfile

from bench_util import quality, run  # bench/ (the script's own folder)



def flip_ele(src, dst):
    """Stellar wants the other orientation than incise writes (it asserts on the first
    'inverted' tet): swap the 2nd and 3rd corner of every element line."""
    with open(src) as f, open(dst, "w") as g:
        header = True
        for line in f:
            w = line.split()
            if not w or w[0].startswith("#"):
                g.write(line)
            elif header:
                g.write(line)
                header = False
            else:
                w[2], w[3] = w[3], w[2]
                g.write(" ".join(w) + "\n")


def default_inputs(incise, build, tmp):
    """The prepared sample liver and CGAL-meshed elephant and fandisk (when present)."""
    out = []
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    liver = os.path.join(repo, "samples", "liver.inr.gz")
    if os.path.exists(liver):
        dst = os.path.join(tmp, "liver.mesh")
        run([incise, "prepare", liver, "--no-improve", "-o", dst])
        out.append(dst)
    for name in ("elephant", "fandisk"):
        off = os.path.join(build, "cgal-data/data/meshes", name + ".off")
        if os.path.exists(off):
            dst = os.path.join(tmp, name + ".mesh")
            run([incise, "tetra", off, "-o", dst, "--size", "3%", "-q"])
            out.append(dst)
        else:
            print("note: %s not found (build with tests to extract CGAL's data set); skipped" % off)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default=".", help="incise build directory (holds cli/incise)")
    ap.add_argument("--mmg", default=shutil.which("mmg3d_O3") or "", help="mmg3d_O3 executable")
    ap.add_argument("--stellar", default=shutil.which("Stellar") or "", help="Stellar executable")
    ap.add_argument("--time-limit", default="10", help="incise improve --time-limit (seconds)")
    ap.add_argument("inputs", nargs="*")
    a = ap.parse_args()
    build = os.path.abspath(a.build)
    incise = os.path.join(build, "cli", "incise")
    if not os.path.exists(incise):
        sys.exit("bench_improve_peers: no incise at %s (run from the build dir or pass --build)" % incise)
    mmg = os.path.abspath(a.mmg) if a.mmg and os.access(a.mmg, os.X_OK) else None
    stellar = os.path.abspath(a.stellar) if a.stellar and os.access(a.stellar, os.X_OK) else None
    if not mmg:
        print("note: no mmg3d_O3 (--mmg %r); Mmg skipped" % a.mmg)
    if not stellar:
        print("note: no Stellar (--stellar %r); Stellar skipped" % a.stellar)
    tmp = tempfile.mkdtemp(prefix="bench_improve_peers_")
    inputs = [os.path.abspath(p) for p in a.inputs] or default_inputs(incise, build, tmp)
    noinsert = os.path.join(tmp, "stellar_noinsert.cfg")
    with open(noinsert, "w") as f:
        f.write("enableinsert 0\n")
    rows = []
    for inp in inputs:
        name = os.path.basename(inp).split(".")[0]
        work = os.path.join(tmp, name)
        os.makedirs(work, exist_ok=True)
        src = os.path.join(work, "in.mesh")
        run([incise, "convert", inp, src])
        base = quality(incise, src)
        rows.append(dict(input=name, tool="input", time=0.0, **base))
        runs = []
        for label, extra in (("incise improve", []), ("incise --insert", ["--insert"])):
            out = os.path.join(work, "incise%d.mesh" % len(runs))
            runs.append((label, lambda out=out, extra=extra: run(
                [incise, "improve", src, "-o", out, "--time-limit", a.time_limit] + extra), out))
        if mmg:
            out = os.path.join(work, "mmg.mesh")
            runs.append(("mmg3d -optim -nosurf", lambda out=out: run(
                [mmg, "-v", "-1", "-optim", "-nosurf", "-in", src, "-out", out]), out))
        if stellar:
            run([incise, "convert", src, os.path.join(work, "in.node")])
            for label, stem, cfg in (("Stellar", "st", None), ("Stellar no insert", "stn", noinsert)):
                shutil.copy(os.path.join(work, "in.node"), os.path.join(work, stem + ".node"))
                flip_ele(os.path.join(work, "in.ele"), os.path.join(work, stem + ".ele"))
                cmd = [stellar] + (["-s", cfg] if cfg else []) + [stem]
                runs.append((label, lambda cmd=cmd: run(cmd, cwd=work), os.path.join(work, stem + ".1.node")))
        for label, fn, out in runs:
            try:
                t = fn()
                rows.append(dict(input=name, tool=label, time=t, **quality(incise, out)))
            except Exception as e:  # one failing tool does not stop the table
                rows.append(dict(input=name, tool=label, error=str(e).splitlines()[0][:120]))
    print("\nworst dihedral angles in degrees, smallest radius ratio (as incise "
          "quality reports it, 1 is regular); tets/in is the ratio to the input's tet count, same run; vol is the relative change of "
          "the volume (the surface moved), bfaces the boundary triangles (the surface was refined)\n")
    print("| mesh | tool | time s | tets | min dih | max dih | min radius ratio | tets/in | vol | bfaces |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in rows:
        if "error" in r:
            print("| %s | %s | failed: %s | | | | | | | |" % (r["input"], r["tool"], r["error"]))
            continue
        r0 = next(x for x in rows if x["input"] == r["input"] and x["tool"] == "input")
        inv = " (%d inverted)" % r["inverted"] if r["inverted"] else ""
        print("| %s | %s | %s | %d%s | %.2f | %.2f | %.3f | %.2f | %.1e | %d |" % (
            r["input"], r["tool"], "-" if r["tool"] == "input" else "%.2f" % r["time"], r["tets"], inv,
            r["min_dih"], r["max_dih"], r["min_rr"], r["tets"] / r0["tets"], r["volume"] / r0["volume"] - 1,
            r["bfaces"]))
    shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
