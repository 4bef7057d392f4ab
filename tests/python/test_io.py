import os
import subprocess

import numpy as np
import pytest

import incise


@pytest.mark.parametrize("ext", ["msh", "mesh", "vtk", "vtu", "node"])
def test_write_read_round_trip_is_exact(tmp_path, box, ext):
    m = incise.TetMesh(box.points, box.tets, np.arange(box.num_tets) % 3 + 1)
    path = str(tmp_path / f"m.{ext}")
    incise.write(m, path)
    back, report = incise.read(path, report=True)
    assert np.array_equal(back.points, m.points)  # shortest round-trip form: bit-exact
    assert np.array_equal(back.tets, m.tets)
    assert np.array_equal(back.labels, m.labels)
    assert report["reoriented_tets"] == 0


def test_fields_need_capacity_rows(tmp_path, box):
    path = str(tmp_path / "f.vtu")
    incise.write(box, path, positions=box.points * 2, point_data={"d": box.points},
                 cell_data={"s": np.ones(box.tet_capacity)})
    assert os.path.getsize(path) > 0
    with pytest.raises(incise.InvalidArgument, match="point_data 'd'"):
        incise.write(box, path, point_data={"d": np.ones(3)})


def test_errors_carry_the_cli_message(tmp_path, incise_exe):
    bad = tmp_path / "bad.msh"
    bad.write_text("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n2\n1 0 0 0\n")
    with pytest.raises(incise.IoError) as e:
        incise.read(str(bad))
    assert str(e.value).startswith(str(bad) + ":")
    cli = subprocess.run([incise_exe, "info", str(bad)], capture_output=True, text=True)
    assert cli.returncode == 1
    assert cli.stderr.strip() == "incise: error: " + str(e.value)


def test_missing_file_is_io_error(tmp_path):
    with pytest.raises(incise.IoError, match="nope.vtu"):
        incise.read(str(tmp_path / "nope.vtu"))


def test_refused_write_keeps_the_destination(tmp_path, box):
    path = tmp_path / "keep.msh"
    path.write_text("precious")
    with pytest.raises(incise.InvalidArgument, match="fields can only be written to .vtu or .vtk, not .*keep.msh"):
        incise.write(box, str(path), point_data={"d": box.points})
    assert path.read_text() == "precious"
    with pytest.raises(incise.IoError, match="unknown tet mesh format"):
        incise.write(box, str(tmp_path / "m.xyz"))


def test_boundary_surface_encloses_the_volume(box):
    v, f = incise.boundary_surface(box)
    assert f.shape == (len(box.boundary_faces()[0]), 3)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    enclosed = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6  # outward: positive
    assert enclosed == pytest.approx(box.volume(), rel=1e-12)


def test_write_refuses_non_finite_or_complex_positions(tmp_path, box):
    out = tmp_path / "p.vtu"
    pos = box.points.copy()
    pos[3, 0] = np.nan
    with pytest.raises(incise.InvalidArgument, match=r"positions: non-finite point coordinate \(point 3\)"):
        incise.write(box, str(out), positions=pos)
    assert not out.exists()
    with pytest.raises(incise.InvalidArgument, match="positions: expected real numbers"):
        incise.write(box, str(out), positions=box.points.astype(complex))
    with pytest.raises(incise.InvalidArgument, match="point_data 'x': expected real numbers"):
        incise.write(box, str(out), point_data={"x": ["a"] * box.vertex_capacity})
    with pytest.raises(incise.InvalidArgument, match="surface triangles: expected integers"):
        incise.write_surface((box.points, [[0.0, 1.5, 2.0]]), str(tmp_path / "s.off"))
