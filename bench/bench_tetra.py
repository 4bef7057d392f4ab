#!/usr/bin/python3
"""Tetrahedralization benchmark: incise (cgal and stuffing engines) vs TetGen and Gmsh.

Meshes the same surfaces at the same target size with every mesher and measures every
output the same way: `incise quality --json` for tets and angles, and a sampled distance
from the output boundary to the input surface (numpy, brute force). Prints a table with
ratios to TetGen, measured in this run.

  /usr/bin/python3 bench/bench_tetra.py [--build DIR] [--size 3%] [surface.off ...]

Run from the build directory (or pass --build); inputs default to CGAL's sphere, elephant
and fandisk. Size semantics are incise's: a circumradius bound, absolute or % of the
bounding-box diagonal; TetGen gets the volume of the regular tet with that circumradius as
its -a bound, Gmsh the size as its element size (surface remeshed at that size).
Needs /usr/bin/python3 (numpy, meshio), tetgen and gmsh on PATH (missing ones are skipped).
"""
import argparse
import math
import os
import shutil
import sys
import tempfile

import meshio
import numpy as np

from bench_util import quality, run  # bench/ (the script's own folder)


def load_surface(path):
    m = meshio.read(path)
    tris = np.concatenate([c.data for c in m.cells if c.type == "triangle"])
    return np.asarray(m.points[:, :3], dtype=float), tris


def boundary_triangles(path):
    m = meshio.read(path)
    tets = np.concatenate([c.data for c in m.cells if c.type == "tetra"])
    faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 1]]])
    key = np.sort(faces, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return np.asarray(m.points[:, :3], dtype=float), faces[counts[inv.ravel()] == 1]


def sample_points(pts, tris, n, rng):
    a, b, c = pts[tris[:, 0]], pts[tris[:, 1]], pts[tris[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    idx = rng.choice(len(tris), size=n, p=area / area.sum())
    r1, r2 = rng.random(n), rng.random(n)
    flip = r1 + r2 > 1
    r1[flip], r2[flip] = 1 - r1[flip], 1 - r2[flip]
    return a[idx] + r1[:, None] * (b[idx] - a[idx]) + r2[:, None] * (c[idx] - a[idx])


def point_triangle_distance(p, a, b, c):
    """Distances from points p (#P,3) to each triangle (#T,3 each): returns (#P,#T)."""
    # Ericson, Real-Time Collision Detection 5.1.5, vectorized.
    p = p[:, None, :]
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp = p - b
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    cp = p - c
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    denom = va + vb + vc
    denom = np.where(np.abs(denom) < 1e-300, 1e-300, denom)
    v = vb / denom
    w = vc / denom
    closest = a + v[..., None] * ab + w[..., None] * ac  # interior
    def pick(mask, value):
        nonlocal closest
        closest = np.where(mask[..., None], value, closest)
    # edges and vertices (order matters: later cases override)
    t = np.clip(d1 / np.where(d1 - d3 == 0, 1e-300, d1 - d3), 0, 1)
    pick((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + t[..., None] * ab)
    t = np.clip(d2 / np.where(d2 - d6 == 0, 1e-300, d2 - d6), 0, 1)
    pick((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + t[..., None] * ac)
    t = np.clip((d4 - d3) / np.where((d4 - d3) + (d5 - d6) == 0, 1e-300, (d4 - d3) + (d5 - d6)), 0, 1)
    pick((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), b + t[..., None] * (c - b))
    pick((d1 <= 0) & (d2 <= 0), np.broadcast_to(a, closest.shape))
    pick((d3 >= 0) & (d4 <= d3), np.broadcast_to(b, closest.shape))
    pick((d6 >= 0) & (d5 <= d6), np.broadcast_to(c, closest.shape))
    return np.linalg.norm(p - closest, axis=-1)


def boundary_distance(out_path, surf_pts, surf_tris, samples=1500):
    pts, tris = boundary_triangles(out_path)
    rng = np.random.default_rng(1)
    q = sample_points(pts, tris, samples, rng)
    a, b, c = surf_pts[surf_tris[:, 0]], surf_pts[surf_tris[:, 1]], surf_pts[surf_tris[:, 2]]
    best = np.full(len(q), np.inf)
    for i in range(0, len(q), 64):
        best[i:i + 64] = point_triangle_distance(q[i:i + 64], a, b, c).min(axis=1)
    return best.max(), best.mean()



def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build", default=".", help="incise build directory (holds cli/incise)")
    ap.add_argument("--size", default="3%", help="target size: absolute or %% of the bbox diagonal")
    ap.add_argument("inputs", nargs="*")
    a = ap.parse_args()
    build = os.path.abspath(a.build)
    incise = os.path.join(build, "cli", "incise")
    if not os.path.exists(incise):
        sys.exit("bench_tetra: no incise at %s (run from the build dir or pass --build)" % incise)
    inputs = a.inputs or [os.path.join(build, "cgal-data/data/meshes", n) for n in ("sphere.off", "elephant.off", "fandisk.off")]
    tmp = tempfile.mkdtemp(prefix="bench_tetra_")
    rows = []
    for inp in inputs:
        name = os.path.splitext(os.path.basename(inp))[0]
        pts, tris = load_surface(inp)
        diag = float(np.linalg.norm(pts.max(0) - pts.min(0)))
        size = float(a.size[:-1]) / 100 * diag if a.size.endswith("%") else float(a.size)
        off = os.path.join(tmp, name + ".off")
        shutil.copy(inp, off)
        stl = os.path.join(tmp, name + ".stl")
        meshio.write_points_cells(stl, pts, [("triangle", tris)])
        runs = []
        out = os.path.join(tmp, name + "_cgal.vtu")
        runs.append(("incise cgal", lambda out=out: run([incise, "tetra", inp, "-o", out, "--size", repr(size), "-q"]), out))
        out = os.path.join(tmp, name + "_stuffing.vtu")
        runs.append(("incise stuffing", lambda out=out: run([incise, "tetra", inp, "-o", out, "--size", repr(size), "-q", "--engine", "stuffing"]), out))
        if shutil.which("tetgen"):
            maxvol = 8 * math.sqrt(3) / 27 * size ** 3  # regular tet with circumradius `size`
            runs.append(("tetgen -pq1.414", lambda: run(["tetgen", "-pq1.414a%.6g" % maxvol, "-Q", off]), os.path.join(tmp, name + ".1.node")))
        if shutil.which("gmsh"):
            geo = os.path.join(tmp, name + ".geo")
            with open(geo, "w") as f:
                f.write('Merge "%s";\nClassifySurfaces{40*Pi/180, 1, 1, Pi};\nCreateGeometry;\n'
                        'Surface Loop(1) = Surface{:};\nVolume(1) = {1};\n'
                        'Mesh.MeshSizeMax = %g;\nMesh.MeshSizeMin = %g;\nMesh.Optimize = 1;\n' % (stl, size, size / 10))
            plain = os.path.join(tmp, name + "_plain.geo")
            with open(plain, "w") as f:  # fallback: the STL triangles as they are
                f.write('Merge "%s";\nSurface Loop(1) = {1};\nVolume(1) = {1};\nMesh.MeshSizeMax = %g;\n' % (stl, size))
            out = os.path.join(tmp, name + "_gmsh.msh")

            def gmsh(out=out, geo=geo, plain=plain):
                try:
                    return run(["gmsh", "-3", "-nt", "1", geo, "-format", "msh22", "-o", out])
                except RuntimeError:
                    return run(["gmsh", "-3", "-nt", "1", plain, "-format", "msh22", "-o", out])
            runs.append(("gmsh -3", gmsh, out))
        for label, fn, out in runs:
            try:
                t = fn()
                q = quality(incise, out)
                vtu = os.path.join(tmp, "measure.vtu")
                run([incise, "convert", out, vtu])
                dmax, dmean = boundary_distance(vtu, pts, tris)
                rows.append(dict(input=name, mesher=label, time=t, size=size, diag=diag, dmax=dmax / diag, dmean=dmean / diag, **q))
            except Exception as e:  # one failing mesher does not stop the table
                msg = [l for l in str(e).splitlines() if "rror" in l] or str(e).splitlines()
                rows.append(dict(input=name, mesher=label, error=msg[-1][:90]))
    print("size %s of the bounding-box diagonal per input; boundary distance in %% of the diagonal; "
          "ratios are to TetGen on the same input, same run\n" % a.size)
    hdr = "%-9s %-16s %8s %8s %7s %7s %7s %8s %8s %7s %7s" % ("input", "mesher", "time s", "tets", "min dih", "max dih",
                                                          "mean rr", "bd max%", "bd mean%", "t/tg", "n/tg")
    print(hdr)
    print("-" * len(hdr))
    for r in rows:
        if "error" in r:
            print("%-9s %-16s failed: %s" % (r["input"], r["mesher"], r["error"]))
            continue
        tg = next((x for x in rows if x["input"] == r["input"] and x["mesher"].startswith("tetgen") and "error" not in x), None)
        rt = "%7.2f" % (r["time"] / tg["time"]) if tg and tg["time"] > 0 else "%7s" % "-"
        rn = "%7.2f" % (r["tets"] / tg["tets"]) if tg and tg["tets"] else "%7s" % "-"
        print("%-9s %-16s %8.3f %8d %7.2f %7.2f %7.3f %8.3f %8.4f %s %s" % (
            r["input"], r["mesher"], r["time"], r["tets"], r["min_dih"], r["max_dih"], r["mean_rr"],
            100 * r["dmax"], 100 * r["dmean"], rt, rn))
    shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
