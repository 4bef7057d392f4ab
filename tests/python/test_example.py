import os
import subprocess
import sys

import incise


def test_example_script_runs(tmp_path, source_dir):
    mesh_path = str(tmp_path / "organ.vtu")
    incise.write(incise.generate_ellipsoid((0.06, 0.04, 0.03), 3), mesh_path)
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, str(source_dir / "samples" / "example.py"), mesh_path, "-o", str(out),
                        "--frames", "3"], capture_output=True, text=True, env=dict(os.environ))
    assert r.returncode == 0, r.stderr
    assert "fem frame 2:" in r.stdout and "springs:" in r.stdout
    back = incise.read(str(out / "fem.vtu"))
    assert back.num_tets == incise.read(mesh_path).num_tets
    bad = subprocess.run([sys.executable, str(source_dir / "samples" / "example.py"), str(tmp_path / "no.vtu"),
                          "-o", str(out)], capture_output=True, text=True)
    assert bad.returncode == 1 and bad.stderr.startswith("example: error: ") and "no.vtu" in bad.stderr
