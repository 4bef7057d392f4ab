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
    assert "fem frame 2:" in r.stdout and "cut step 5:" in r.stdout and "springs:" in r.stdout
    # The sag is physical: of the order of free fall over the steps taken (dead vertex slots,
    # left by the cut's improvement, count as not moving: their stale values read 3000x that).
    line = next(l for l in r.stdout.splitlines() if l.startswith("springs:"))
    dt = float(line.split(" dt ")[1].split(" s,")[0])
    sag = float(line.split("max sag ")[1].split(" m")[0])
    assert 0 < sag <= 2 * 0.5 * 9.81 * (200 * dt) ** 2
    back = incise.read(str(out / "fem.vtu"))
    assert back.num_tets == incise.read(mesh_path).num_tets
    assert incise.read(str(out / "cut.vtu")).num_tets > back.num_tets
    bad = subprocess.run([sys.executable, str(source_dir / "samples" / "example.py"), str(tmp_path / "no.vtu"),
                          "-o", str(out)], capture_output=True, text=True)
    assert bad.returncode == 1 and bad.stderr.startswith("example: error: ") and "no.vtu" in bad.stderr
