#!/usr/bin/env python3
"""`mpirun -np N incise simulate` with "solver": {"backend": "petsc"} gives the serial run's
displacement: the scene is run once by one process with the direct solver (the reference) and
once over N ranks with PETSc, both at a tight tolerance, and every written frame is compared.

usage: mpi_equals_serial.py INCISE SCENE RANKS WORKDIR [--frames F] [--extra JSON] [--shared-solve]
       mpi_equals_serial.py INCISE --trade SCENE RANKS WORKDIR (incise trade's table over RANKS)
Exit 0 when every frame's displacement agrees to 1e-6 of its largest value (and, with
--shared-solve, when PETSc's -ksp_view shows the system's matrix spread over all RANKS).
Also: mpi_equals_serial.py INCISE --bad-scene RANKS WORKDIR: a bad scene gives one line on
stderr and exit 1 from every rank, within the timeout (no rank hangs)."""
import json
import os
import subprocess
import sys

import meshio
import numpy as np


def mpirun(ranks):
    # As root OpenMPI wants both the flag and the confirmation; --oversubscribe: more ranks than cores.
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    return ["mpirun", "--oversubscribe", "-np", str(ranks)], env


def variant(scene_path, out_path, solver, extra):
    with open(scene_path) as f:
        s = json.load(f)
    mesh = s.get("mesh")
    if isinstance(mesh, str) and not os.path.isabs(mesh):
        s["mesh"] = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(scene_path)), mesh))
    s["solver"] = solver
    s.update(extra)
    with open(out_path, "w") as f:
        json.dump(s, f, indent=1)


def frames(d):
    return sorted(n for n in os.listdir(d) if n.startswith("frame_") and n.endswith(".vtu"))


def trade(exe, scene, ranks, work):
    """`mpirun -np N incise trade` writes the table one process writes (the columns that do not
    time anything; no budgeted rows, whose iterations depend on the clock)."""
    os.makedirs(work, exist_ok=True)
    cmd, env = mpirun(ranks)
    grid = ["--models", "fem-linear", "fem-corotational", "--formulations", "standard", "nodal-averaged",
            "--preconditioners", "jacobi", "amg", "--tolerances", "1e-4", "1e-8", "--budgets", "0",
            "--resolutions", "-1", "0", "--frames", "3", "-q"]
    one, many = os.path.join(work, "one"), os.path.join(work, "many")
    for d in (one, many):
        subprocess.run(["rm", "-rf", d], check=True)
    subprocess.run([exe, "trade", scene, "-o", one] + grid, check=True, timeout=300, stdout=subprocess.DEVNULL)
    subprocess.run(cmd + [exe, "trade", scene, "-o", many] + grid, check=True, env=env, timeout=300,
                   stdout=subprocess.DEVNULL)
    import csv
    rows = []
    for d in (one, many):
        with open(os.path.join(d, "trade.csv")) as f:
            rows.append(list(csv.DictReader(f)))
    timed = {"ms_per_frame", "settle_ms", "pareto"}
    if len(rows[0]) != len(rows[1]) or not rows[0]:
        print("row counts differ:", len(rows[0]), len(rows[1]))
        return 1
    for a, b in zip(*rows):
        for k in a:
            if k in timed:
                continue
            try:
                same = abs(float(a[k]) - float(b[k])) <= 1e-6 * max(abs(float(a[k])), 1e-12)
            except ValueError:
                same = a[k] == b[k]
            if not same:
                print("differs:", k, a, b)
                return 1
    print(len(rows[0]), "rows alike over", ranks, "ranks")
    return 0


def main(argv):
    if argv[2] == "--trade":
        return trade(argv[1], argv[3], int(argv[4]), argv[5])
    exe, scene, ranks, work = argv[1], argv[2], int(argv[3]), argv[4]
    os.makedirs(work, exist_ok=True)
    cmd, env = mpirun(ranks)
    if scene == "--bad-scene":
        bad = os.path.join(work, "bad.json")
        with open(bad, "w") as f:
            f.write('{"mesh": {"generate": "box"}, "model": "fem-linear", "solver": {"backend": "petsc", "tolerance": -1}}')
        # mpirun -q: without its own notes on the non-zero exit, stderr is rank 0's one line.
        p = subprocess.run(cmd[:1] + ["-q"] + cmd[1:] + [exe, "simulate", bad, "-o", os.path.join(work, "bad-out")],
                           env=env, capture_output=True, text=True, timeout=60)
        lines = p.stderr.splitlines()
        print(p.stderr)
        ok = p.returncode == 1 and len(lines) == 1 and lines[0].startswith("incise: error: ")
        ok = ok and "bad.json" in lines[0] and "solver.tolerance" in lines[0]
        ok = ok and not os.path.exists(os.path.join(work, "bad-out"))
        return 0 if ok else 1
    extra_args = []
    extra = {}
    shared = False
    i = 5
    while i < len(argv):
        if argv[i] == "--shared-solve":
            shared = True
            i += 1
            continue
        if argv[i] == "--frames":
            extra_args += ["--frames", argv[i + 1]]
        elif argv[i] == "--extra":
            extra = json.loads(argv[i + 1])
        i += 2
    ref, par = os.path.join(work, "serial.json"), os.path.join(work, "petsc.json")
    variant(scene, ref, {"method": "direct"}, extra)
    variant(scene, par, {"backend": "petsc", "tolerance": 1e-10, "max_iterations": 5000}, extra)
    ref_out, par_out = os.path.join(work, "serial"), os.path.join(work, "petsc")
    for d in (ref_out, par_out):
        subprocess.run(["rm", "-rf", d], check=True)
    subprocess.run([exe, "simulate", ref, "-o", ref_out, "-q"] + extra_args, check=True, timeout=300)
    if shared:
        # PETSc prints each solver's set-up: the system's matrix must live on every rank.
        env = dict(env, PETSC_OPTIONS="-ksp_view")
        p = subprocess.run(cmd + ["-x", "PETSC_OPTIONS", exe, "simulate", par, "-o", par_out, "-q"] + extra_args,
                           check=True, env=env, timeout=300, capture_output=True, text=True)
        want = f"Mat Object: {ranks} MPI process" if ranks > 1 else "Mat Object: 1 MPI process"
        if not any(line.strip().startswith(want) for line in p.stdout.splitlines()):
            print("no matrix over", ranks, "ranks in -ksp_view")
            return 1
    else:
        subprocess.run(cmd + [exe, "simulate", par, "-o", par_out, "-q"] + extra_args, check=True, env=env, timeout=300)
    fr, fp = frames(ref_out), frames(par_out)
    if fr != fp or not fr:
        print("frames differ:", fr, fp)
        return 1
    worst = 0.0
    for name in fr:
        a = meshio.read(os.path.join(ref_out, name))
        b = meshio.read(os.path.join(par_out, name))
        da, db = a.point_data["displacement"], b.point_data["displacement"]
        if da.shape != db.shape:
            print(name, "shapes differ", da.shape, db.shape)
            return 1
        scale = max(np.abs(da).max(), 1e-300)
        err = np.abs(da - db).max() / scale
        worst = max(worst, err)
        print(f"{name}: {da.shape[0]} vertices, max |u| {scale:.4g}, relative difference {err:.2e}")
    return 0 if worst <= 1e-6 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
