"""incise: tetrahedral meshing, quality reports, cutting and simulation of soft tissue.

Meshes are incise.TetMesh (stable vertex / tet ids; arrays are numpy copies, rows indexed by
id). Errors raise incise.Error subclasses (IoError, InvalidMesh, InvalidArgument) carrying the
message the command line prints. See docs/python.md.
"""
import numpy as _np

from ._incise import *  # noqa: F401,F403
from ._incise import Error, FemSimulation, SpringSimulation, TetMesh, load_scene  # noqa: F401


def vertices_in_box(mesh, lo, hi, tol=None):
    """Ids of the live vertices with tets inside the box [lo, hi] (tol: 1e-9 of the mesh
    diagonal by default, the rule scenes use)."""
    ids = mesh.vertex_ids
    tets = mesh.tets
    used = _np.zeros(mesh.vertex_capacity, dtype=bool)
    used[tets.ravel()] = True
    pts = mesh.points
    ids = ids[used[ids]]
    p = pts[ids]
    if tol is None:
        tol = 1e-9 * float(_np.linalg.norm(p.max(axis=0) - p.min(axis=0))) if len(p) else 0.0
    lo = _np.asarray(lo, dtype=float) - tol
    hi = _np.asarray(hi, dtype=float) + tol
    return ids[_np.all((p >= lo) & (p <= hi), axis=1)]


def simulation_from_scene(path):
    """(mesh, simulation) built from a scene file: its mesh, model, materials, solver and fixed
    boxes. Loads over time (forces, probes, ramps) are played by run_scene(), not here."""
    scene = load_scene(path)
    mesh = scene.mesh()
    if scene.model == "springs":
        sim = SpringSimulation(mesh, scene.materials, damping=scene.damping, **scene.springs)
    else:
        kind = "corotational" if scene.model == "fem-corotational" else "linear"
        sim = FemSimulation(mesh, scene.materials, kind=kind, dynamic=scene.integrator == "implicit-euler",
                            dt=scene.dt, damping=scene.damping, **scene.solver)
    for lo, hi in scene.fixed:
        sim.fix(vertices_in_box(mesh, lo, hi))
    return mesh, sim
