"""Shared by the Python benchmarks: running a tool with its wall time, and the whole-mesh
figures of `incise quality --json` (bench_tetra.py, bench_improve_peers.py); the sagging body
and its slot cut of the springs benches (bench_springs_cut.py, bench_springs_stable_step.py)."""
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


class SaggingBody:
    """The springs benches' setup: a mesh (the sample liver) held on its low-x 15% under gravity,
    of a soft material that sags a few percent of its size (rho g L / E = 0.03, nu 0.45), and
    the slot cut of issue 41: a vertical blade over the middle half of the width, half the
    height down in 10 steps, then finish()."""

    def __init__(self, incise, path):
        import numpy as np
        self.incise, self.np = incise, np
        self.mesh = incise.read(path)
        self.mesh.take_change()
        p = self.mesh.points
        self.lo, self.hi = p.min(0), p.max(0)
        self.ext = self.hi - self.lo
        self.material = incise.Material(young=1000.0 * 9.81 * self.ext.max() / 0.03, poisson=0.45, density=1000.0)
        self.gravity = (0.0, 0.0, -9.81)

    def held(self, m=None):
        """The vertices of m (default: the body's mesh) on the low-x 15% of the body."""
        m = self.mesh if m is None else m
        return self.np.nonzero(m.points[:, 0] < self.lo[0] + 0.15 * self.ext[0])[0]

    def slot_bounds(self):
        """The rectangle the slot's blade sweeps: its plane x = c and its y and z ranges."""
        lo, hi, ext = self.lo, self.hi, self.ext
        return (lo[0] + 0.5 * ext[0], (lo[1] + 0.25 * ext[1], lo[1] + 0.75 * ext[1]),
                (hi[2] + 0.05 * ext[2] - 0.55 * ext[2], hi[2] + 0.05 * ext[2]))

    def distance_to_slot(self, points):
        """Each point's distance to the rectangle the slot's blade sweeps."""
        np = self.np
        x, (y0, y1), (z0, z1) = self.slot_bounds()
        dy = np.maximum(0, np.maximum(y0 - points[:, 1], points[:, 1] - y1))
        dz = np.maximum(0, np.maximum(z0 - points[:, 2], points[:, 2] - z1))
        return np.sqrt((points[:, 0] - x) ** 2 + dy ** 2 + dz ** 2)

    def cut_slot(self, follow):
        """Cuts the slot through the mesh, giving each step's change to follow(change) before the
        mesh is edited again. A slot, not a cut across the whole width: nothing hangs by a thread
        (a cut across the whole width left a lobe on a neck that swung down)."""
        np = self.np
        x, (y0, y1), (z0, z1) = self.slot_bounds()
        a0, b0 = np.array([x, y0, z1]), np.array([x, y1, z1])
        step = np.array([0.0, 0.0, (z0 - z1) / 10])
        cutter = self.incise.Cutter(self.mesh)
        cutter.start(a0, b0)
        for k in range(1, 11):
            follow(cutter.advance(a0 + k * step, b0 + k * step)["change"])
        follow(cutter.finish()["change"])
