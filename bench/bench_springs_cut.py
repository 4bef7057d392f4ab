#!/usr/bin/python3
"""Springs at rest before and after a cut, against a converged reference (issue 41, section 3).

The sample liver (or MESH) held on its low-x 15%, sagging under gravity; at rest, each model's
displacement against a converged reference (relative L2 over the mesh's vertices), before and
after a progressive cut (a vertical blade over the middle half of the width, half the height
down, 10 steps, then finish()). The reference is corotational Taylor-Hood FEM (quadratic
displacement, linear pressure: `mixed-quadratic`, incise trade's reference) on the mesh refined
1:8 (refine_uniform, which keeps the cut open), solved afresh before and after the cut:
quadratic tets do not follow a cut, but they can be built on the cut mesh. Linear FEM (standard
and nodal-averaged) and Taylor-Hood on the mesh itself are rows too, so each spring ratio reads
beside FEM's own (a cut leaves a crack front, where every discretization's error grows). The
spring models are built before the cut and follow it through the cut's change records
(SpringSimulation.apply), as in a scene. The fifth column builds each model afresh on the cut
mesh: at rest it must equal the one that followed the cut. The last five split the error
between the vertices within two mean edges of the rectangle the blade swept ("near": the cut
faces and the crack front) and the rest ("far"), each as its share of the relative L2 error
(their squares add up to the whole), and give the far part's growth through the cut.

  /usr/bin/python3 bench/bench_springs_cut.py [--build DIR] [--only TEXT] [--no-fem] [MESH]

--only keeps the spring rows whose name contains TEXT (repeatable); --no-fem leaves out the
linear FEM and Taylor-Hood rows (the reference is still solved).
"""
import argparse
import os
import sys

import numpy as np

from bench_util import SaggingBody  # bench/ (the script's own folder)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser()
    ap.add_argument("mesh", nargs="?", default=os.path.join(here, "..", "samples", "liver.msh"))
    ap.add_argument("--build", default=os.path.join(here, "..", "build"))
    ap.add_argument("--only", action="append", default=[])
    ap.add_argument("--no-fem", action="store_true")
    a = ap.parse_args()
    sys.path.insert(0, os.path.join(a.build, "python"))
    import incise

    body = SaggingBody(incise, a.mesh)
    mesh, mat, g, held = body.mesh, body.material, body.gravity, body.held

    def fem_rest(m, formulation="mixed-quadratic"):
        f = incise.FemSimulation(m, mat, kind="corotational", formulation=formulation, gravity=g,
                                 nonlinear_iterations=4, tolerance=1e-9)
        f.fix(held(m))
        for _ in range(4):
            f.step()
        return f.displacement.copy()

    configs = [("default: volume nodal 0.9 across-faces", dict()),
               ("volume tet", dict(nodal_volume=False, across_faces=False)),
               ("volume nodal", dict(nodal_share=1.0, across_faces=False)),
               ("volume tet (fitted)", dict(nodal_volume=False, stiffness="fitted")),
               ("volume nodal 0.9 (fitted)", dict(stiffness="fitted")),
               ("volume tet across-faces", dict(nodal_volume=False)),
               ("volume nodal across-faces", dict(nodal_share=1.0)),
               ("volume nodal 0.75 across-faces", dict(nodal_share=0.75)),
               ("volume nodal across-faces, guard 0.5", dict(nodal_share=1.0, inversion_guard=0.5)),
               ("volume nodal across-faces, guard 0.25", dict(nodal_share=1.0, inversion_guard=0.25))]
    if a.only:
        configs = [c for c in configs if any(t in c[0] for t in a.only)]
    springs = []
    for name, kw in configs:
        s = incise.SpringSimulation(mesh, mat, damping=10.0, compute_energy=False, **kw)
        s.fix(held(mesh))
        s.set_gravity(g)
        springs.append((name, s))

    def settle(s):
        # Damped steps to rest: one huge implicit step (a Newton step) diverges on the cut liver
        # (its linearization is near singular there); steps of 0.1 s at 10/s damping do not. Until
        # no vertex moves more than 1e-6 of the largest displacement over 100 steps (a fixed 300
        # steps, as this bench took before, stopped short: the slow lobe was still moving).
        u = s.displacement.copy()
        for _ in range(100):
            for _ in range(100):
                s.step(0.1, "implicit-euler")
            v = s.displacement.copy()
            moved = np.abs(v - u).max()
            u = v
            if moved <= 1e-6 * np.abs(u).max():
                return u
        sys.exit("springs did not settle in 10,000 steps")

    # Where the error sits: the vertices within two mean edges of the blade's swept rectangle
    # ("near", the crack front and the cut faces) and the rest ("far"); each part's share of the
    # relative L2 error (their squares add up to the whole's).
    t = mesh.tets
    mean_edge = np.mean([np.linalg.norm(mesh.points[t[:, i]] - mesh.points[t[:, j]], axis=1).mean()
                         for i in range(4) for j in range(i)])

    def error(u, ref, alive):
        d = (u - ref)[alive]
        near = body.distance_to_slot(mesh.points[alive]) < 2 * mean_edge
        r = np.linalg.norm(ref[alive])
        return np.linalg.norm(d) / r, np.linalg.norm(d[near]) / r, np.linalg.norm(d[~near]) / r

    def reference(m):
        # Taylor-Hood on the mesh refined 1:8, read back at m's vertex ids (refine_uniform keeps a
        # compact mesh's ids; compact() numbers the live vertices in id order).
        c = m.copy()
        vmap, _ = c.compact()
        u = fem_rest(incise.refine_uniform(c))
        out = np.zeros((m.vertex_capacity, 3))
        live = vmap >= 0
        out[live] = u[vmap[live]]
        return out

    fems = [] if a.no_fem else ["standard", "nodal-averaged", "mixed-quadratic"]
    alive = np.unique(mesh.tets)
    ref = reference(mesh)
    before = {name: error(settle(s), ref, alive) for name, s in springs}
    for f in fems:
        before["FEM " + f] = error(fem_rest(mesh, f), ref, alive)

    def follow(change):  # each change before the mesh is edited again
        for _, s in springs:
            s.apply(change)

    body.cut_slot(follow)
    alive = np.unique(mesh.tets)
    ref = reference(mesh)
    print(f"# {os.path.basename(a.mesh)}: {mesh.num_tets} tets after the cut; at rest against "
          "corotational Taylor-Hood FEM on the mesh refined 1:8 (relative L2)")
    print("model,uncut,cut,cut/uncut,cut (built on the cut mesh),uncut near,uncut far,cut near,cut far,"
          "far cut/uncut")

    def row(name, b, after, built):
        print(f"{name},{b[0]:.3f},{after[0]:.3f},{after[0] / b[0]:.2f},{built:.3f},{b[1]:.3f},{b[2]:.3f},"
              f"{after[1]:.3f},{after[2]:.3f},{after[2] / b[2]:.2f}", flush=True)

    for f in fems:
        after = error(fem_rest(mesh, f), ref, alive)
        row("FEM " + f, before["FEM " + f], after, after[0])
    for name, s in springs:
        after = error(settle(s), ref, alive)
        fresh = incise.SpringSimulation(mesh, mat, damping=10.0, compute_energy=False, **dict(configs)[name])
        fresh.fix(held(mesh))
        fresh.set_gravity(g)
        row(name, before[name], after, error(settle(fresh), ref, alive)[0])


if __name__ == "__main__":
    main()
