"""Shared by the Python benchmarks (bench_tetra.py, bench_improve_peers.py): running a tool
with its wall time, and the whole-mesh figures of `incise quality --json`."""
import json
import os
import subprocess
import time


def run(cmd, cwd=None):
    """Runs cmd; returns its wall time in seconds, raises with the tool's last message."""
    t0 = time.perf_counter()
    r = subprocess.run(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    dt = time.perf_counter() - t0
    if r.returncode != 0:
        tail = (r.stderr.strip() or r.stdout.strip()).splitlines()[-1:] or ["exit %d" % r.returncode]
        raise RuntimeError("%s failed: %s" % (os.path.basename(cmd[0]), tail[0][:200]))
    return dt


def quality(incise, path):
    """Tet count, dihedral extremes, radius ratio (min and mean), inverted count, volume and
    boundary face count of the mesh at `path`, from `incise quality --json`."""
    r = subprocess.run([incise, "quality", "--json", path], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        raise RuntimeError("incise quality " + path + ": " + r.stderr.strip())
    j = json.loads(r.stdout)
    m = j["metrics"]
    return {"tets": j["counts"]["tets"], "min_dih": m["min_dihedral"]["min"], "max_dih": m["max_dihedral"]["max"],
            "min_rr": m["radius_ratio"]["min"], "mean_rr": m["radius_ratio"]["mean"],
            "inverted": j["elements"]["inverted"], "volume": j["volume"], "bfaces": j["counts"]["boundary_faces"]}
