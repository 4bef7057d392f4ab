import os
import pathlib

import numpy as np
import pytest

import incise

pytestmark = pytest.mark.skipif(not incise.have_tetra, reason="built without CGAL (INCISE_WITH_CGAL=OFF)")


def cgal_mesh(name):
    path = pathlib.Path(os.environ.get("INCISE_CGAL_DATA_DIR", "")) / "meshes" / name
    if not path.exists():
        pytest.skip(f"{path} not extracted")
    return str(path)


@pytest.mark.parametrize("engine", ["cgal", "stuffing"])
def test_tetrahedralize_a_closed_surface(engine):
    mesh, report = incise.tetrahedralize(cgal_mesh("cube.off"), size="5%" if engine == "stuffing" else "10%",
                                         engine=engine, report=True)
    mesh.validate(check_manifold_boundary=True)
    assert mesh.num_tets > 0 and report["engine"] == engine
    lo, hi = mesh.points.min(axis=0), mesh.points.max(axis=0)
    assert mesh.volume() == pytest.approx(np.prod(hi - lo), rel=0.03)  # corners round off at this size
    q = incise.quality(mesh)
    assert q["elements"]["inverted"] == 0


def test_tetrahedralize_errors(tmp_path):
    with pytest.raises(incise.Error, match="nothing.off"):
        incise.tetrahedralize(str(tmp_path / "nothing.off"))
    with pytest.raises(incise.InvalidArgument):
        incise.tetrahedralize(cgal_mesh("cube.off"), size="-3%")
    with pytest.raises(incise.InvalidArgument, match="engine"):
        incise.tetrahedralize(cgal_mesh("cube.off"), engine="tetgen")


def test_tetrahedralize_a_surface_in_memory(tmp_path):
    # The boundary of a box, as arrays: meshing it again gives the box's volume.
    box = incise.generate_box((2.0, 1.0, 1.0), (2, 1, 1))
    surface = incise.boundary_surface(box)
    mesh = incise.tetrahedralize(surface, size="8%", engine="cgal")
    mesh.validate(check_manifold_boundary=True)
    assert mesh.volume() == pytest.approx(2.0, rel=0.03)
    path = str(tmp_path / "box.off")
    incise.write_surface(surface, path)
    v, f = incise.read_surface(path)
    assert np.array_equal(v, surface[0]) and np.array_equal(f, surface[1])
    with pytest.raises(incise.InvalidArgument, match="triangle #0 references vertex 99"):
        incise.tetrahedralize((v, [[0, 1, 99]]))
