import json
import subprocess

import numpy as np
import pytest

import incise


def test_kuhn_golden_values(box):
    q = incise.quality(box)
    assert q["schema"] == "incise.quality/1"
    assert q["counts"]["tets"] == box.num_tets
    m = q["metrics"]
    # every tet of the box is a Kuhn tet
    assert m["mean_ratio"]["min"] == pytest.approx(0.755953, abs=1e-6)
    assert m["radius_ratio"]["max"] == pytest.approx(0.717439, abs=1e-6)
    assert m["volume_length"]["mean"] == pytest.approx(0.657267, abs=1e-6)
    assert m["min_dihedral"]["min"] == pytest.approx(45.0)
    assert q["boundary"]["closed"] and q["boundary"]["manifold"]
    assert q["components"] == 1
    assert q["elements"] == {"inverted": 0, "degenerate": 0, "slivers": 0, "forced_slivers": 0, "thin_slivers": 0}
    per_tet = incise.tet_quality(box, "mean_ratio")
    assert per_tet.shape == (box.num_tets,)
    assert np.allclose(per_tet, 0.755953, atol=1e-6)


def test_same_dict_as_the_cli(tmp_path, box, incise_exe):
    path = str(tmp_path / "box.vtu")
    incise.write(box, path)
    # incise.quality() has the formula's solver estimate only; the CLI's measured one (a short
    # CG solve, with its timings) is left out here.
    cli = subprocess.run([incise_exe, "quality", path, "--json", "--worst", "3", "--solver-estimate", "formula"],
                         capture_output=True, text=True, check=True)
    assert incise.quality(path, worst=3) == json.loads(cli.stdout)


def test_deformed_positions_and_options(box):
    squashed = box.points * np.array([1.0, 1.0, 1e-3])
    q = incise.quality(box, positions=squashed, sliver_angle=5.0, worst=2)
    assert q["elements"]["slivers"] == box.num_tets
    assert len(q["worst"]["elements"]) == 2
    with pytest.raises(incise.InvalidArgument):
        incise.quality(box, metric="no_such_metric")
    with pytest.raises(incise.InvalidArgument, match="positions"):
        incise.quality(box, positions=np.zeros((2, 3)))
    assert "mean_ratio" in incise.metrics
    assert "mean" in incise.quality_text(box).lower()
