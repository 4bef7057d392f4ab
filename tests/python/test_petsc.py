"""FemSimulation(..., backend="petsc"): the same FEM solved by PETSc (CG + GAMG) in this process,
equal to the direct solve; a build without PETSc says so in one error."""
import numpy as np
import pytest

import incise


def load(mesh, sim):
    x = mesh.points[:, 0]
    sim.fix(np.nonzero(x == 0)[0])
    sim.prescribe(np.nonzero(x == x.max())[0], (0, 0, -0.05))


@pytest.mark.parametrize("kind,formulation,dynamic", [
    ("linear", "standard", False), ("corotational", "nodal-averaged", False), ("corotational", "edge-smoothed", True)])
def test_petsc_backend_equals_the_direct_solve(box, kind, formulation, dynamic):
    mat = incise.Material(young=1e4, poisson=0.45, density=10)
    common = dict(kind=kind, formulation=formulation, dynamic=dynamic, dt=0.05, gravity=(0, 0, -1))
    try:
        petsc = incise.FemSimulation(box, mat, backend="petsc", tolerance=1e-11, **common)
        load(box, petsc)
        stats = petsc.step()
    except Exception as e:  # a build without PETSc: one clear error, nothing else
        assert "built without PETSc" in str(e)
        return
    assert stats["info"] == "success" and stats["iterations"] > 0
    direct = incise.FemSimulation(box, mat, method="direct", **common)
    load(box, direct)
    direct.step()
    for _ in range(2):
        u, ref = petsc.displacement, direct.displacement
        assert np.linalg.norm(u - ref) <= 1e-8 * np.linalg.norm(ref)
        stats = petsc.step()  # a repeated linear static frame starts at its solution: 0 iterations
        direct.step()
        assert stats["info"] == "success"
        u, ref = petsc.displacement, direct.displacement
        assert np.linalg.norm(u - ref) <= 1e-8 * np.linalg.norm(ref)


def test_petsc_options_reach_the_solver(box):
    mat = incise.Material(young=1e4, poisson=0.3)
    try:
        sim = incise.FemSimulation(box, mat, backend="petsc", petsc_options="-ksp_type no_such_method")
        load(box, sim)
        with pytest.raises(Exception, match="no_such_method"):
            sim.step()
    except Exception as e:
        assert "built without PETSc" in str(e)
