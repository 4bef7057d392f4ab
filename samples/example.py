#!/usr/bin/python3
"""incise from Python: prepare (or generate) a tet mesh, report its quality, simulate it, cut it.

  PYTHONPATH=build/python /usr/bin/python3 samples/example.py [INPUT] [-o OUT_DIR]

INPUT is a tet mesh (.vtu .msh ...), a closed surface or a labeled image (.inr.gz; meshed
with CGAL when incise was built with it). Default: samples/liver.inr.gz when CGAL is built,
else a generated ellipsoid. The organ is clamped on its lowest 10 % (by height) and pressed
from above; the frames go to OUT_DIR (default example-out/) for ParaView.
"""
import argparse
import os
import sys

import numpy as np

import incise

here = os.path.dirname(os.path.abspath(__file__))
ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("input", nargs="?", help="tet mesh, surface or labeled image")
ap.add_argument("-o", "--out", default="example-out", help="output directory")
ap.add_argument("--frames", type=int, default=10, help="FEM frames")
args = ap.parse_args()
os.makedirs(args.out, exist_ok=True)

# 1. Prepare: mesh an image or surface, read a tet mesh, or generate one.
try:
    source = args.input or (os.path.join(here, "liver.inr.gz") if incise.have_tetra else None)
    if source is None:
        mesh = incise.generate_ellipsoid((0.06, 0.04, 0.03), 6)
        print("prepare: generated an ellipsoid (incise built without CGAL)")
    elif source.endswith((".msh", ".mesh", ".vtk", ".vtu", ".node", ".ele")):
        mesh = incise.read(source)
        print(f"prepare: read {source}")
    else:
        mesh, rep = incise.tetrahedralize(source, size="3%", report=True)
        print(f"prepare: {rep['summary']}")
        if source.endswith((".inr", ".inr.gz")):  # images are in millimetres: this script is SI
            mesh = incise.TetMesh(mesh.points * 1e-3, mesh.tets, mesh.labels)
            print("prepare: the image's millimetres converted to metres")
except incise.Error as e:  # same message as the command line
    sys.exit(f"example: error: {e}")
incise.write(mesh, os.path.join(args.out, "mesh.vtu"))

# 2. Report: the same dict as `incise quality --json`.
q = incise.quality(mesh)
dih = q["metrics"]["min_dihedral"]
print(f"quality: {q['counts']['tets']} tets, {q['counts']['vertices']} vertices, volume {q['volume']:.4g}, "
      f"dihedral {dih['min']:.1f}..{q['metrics']['max_dihedral']['max']:.1f} deg, "
      f"slivers {q['elements']['slivers']}, closed boundary {q['boundary']['closed']}, "
      f"estimated CG iterations {q['solver']['cg_iterations']}")

# 3. Simulate: clamp the lowest 10 % by height, push the top 10 % down over the frames.
pts = mesh.points
lo, hi = pts.min(axis=0), pts.max(axis=0)
height = hi[2] - lo[2]
bottom = incise.vertices_in_box(mesh, lo, (hi[0], hi[1], lo[2] + 0.1 * height))
top = incise.vertices_in_box(mesh, (lo[0], lo[1], hi[2] - 0.1 * height), hi)
# incise has no units of its own (docs/scene.md#units): this script keeps to SI, so the mesh is in
# metres, the modulus in Pa, the density in kg/m^3 and g in m/s^2.
soft_tissue = incise.Material(young=3e3, poisson=0.45, density=1000)  # Pa, -, kg/m^3
fem = incise.FemSimulation(mesh, soft_tissue, kind="corotational", tolerance=1e-6)
fem.fix(bottom)
for frame in range(args.frames):
    fem.prescribe(top, (0, 0, -0.1 * height * (frame + 1) / args.frames))
    s = fem.step()
    u = np.linalg.norm(fem.displacement, axis=1).max()
    print(f"fem frame {frame}: {s['iterations']} CG iterations, residual {s['relative_residual']:.2e}, "
          f"{s['solve_ms']:.1f} ms, max displacement {u:.4g}")
incise.write(mesh, os.path.join(args.out, "fem.vtu"), positions=fem.positions,
             point_data={"displacement": fem.displacement}, cell_data={"von_mises": fem.von_mises()})

# 4. Cut: a blade across the organ at mid-length enters from above, 40 % of the height deep in
# 5 steps, cutting the deformed shape; each step's change goes to the FEM model locally.
cutter = incise.Cutter(mesh)
mid, width = 0.5 * (lo + hi), hi - lo
a = np.array([mid[0] + 0.013 * width[0], lo[1] - 0.1 * width[1], hi[2] + 0.05 * height])
b = np.array([a[0], hi[1] + 0.1 * width[1], a[2]])
mesh.take_change()  # earlier edits (none here) must be handed out before cutting
cutter.start(a, b)
for k in range(1, 6):
    down = np.array([0.0, 0.0, -0.45 * height * k / 5])
    r = cutter.advance(a + down, b + down, positions=fem.positions)
    fem.apply(r["change"])
    s = fem.step()
    print(f"cut step {k}: {r['tets_cut']} tets cut, +{r['tets_added']} tets, {r['vertices_duplicated']} vertices "
          f"duplicated, {r['ms']:.1f} ms; then {s['iterations']} CG iterations")
r = cutter.finish(positions=fem.positions)  # the blade withdrawn: the tets it stopped in are cut
fem.apply(r["change"])
fem.step()
incise.write(mesh, os.path.join(args.out, "cut.vtu"), positions=fem.positions,
             point_data={"displacement": fem.displacement})

# The same organ as a spring-mass model, falling onto its clamp under gravity.
springs = incise.SpringSimulation(mesh, soft_tissue, damping=20.0)
springs.fix(bottom)
springs.set_gravity((0, 0, -9.81))
dt = 0.5 * springs.stable_time_step()
for _ in range(200):
    springs.step(dt)
sag = -springs.displacement[:, 2].min()
print(f"springs: {springs.num_springs} springs, dt {dt:.2e} s, 200 steps, max sag {sag:.4g} m ({1e3 * sag:.3g} mm)")
print(f"outputs in {args.out}/ (mesh.vtu, fem.vtu, cut.vtu)")
