import gc

import numpy as np
import pytest

import incise


def clamp_and_pull(mesh, sim, stretch):
    x = mesh.points[:, 0]
    sim.fix(np.nonzero(x == 0)[0])
    sim.prescribe(np.nonzero(x == x.max())[0], (stretch, 0, 0))


@pytest.mark.parametrize("backend", ["matrix-free", "assembled"])
def test_fem_reproduces_uniaxial_stretch(box, backend):
    # nu = 0: clamping the ends adds no lateral stress, so u = (d x / L, 0, 0) exactly and
    # sigma_xx = E d / L; linear tets represent the linear field exactly.
    young, d = 2e5, 1e-3
    sim = incise.FemSimulation(box, incise.Material(young=young, poisson=0.0), backend=backend, tolerance=1e-12)
    clamp_and_pull(box, sim, d)
    stats = sim.step()
    assert stats["info"] == "success" and stats["relative_residual"] <= 1e-12
    assert stats["iterations"] > 0
    u = sim.displacement
    assert u.shape == (box.vertex_capacity, 3)
    assert np.allclose(u[:, 0], d * box.points[:, 0], atol=1e-12)
    assert np.allclose(u[:, 1:], 0, atol=1e-12)
    assert np.allclose(sim.von_mises(), young * d, rtol=1e-8)
    assert np.allclose(sim.positions, box.points + u)
    again = sim.step()  # nothing changed: warm start resumes at the solution
    assert again["iterations"] <= 1


def test_fem_frame_budget_takes_off_what_the_frame_spent(box):
    # A budget already spent (by a cut, say) leaves the solve one iteration; the next frames
    # resume the interrupted solve and converge.
    sim = incise.FemSimulation(box, incise.Material(1e5, 0.45), tolerance=1e-10, budget_ms=1e5,
                               preconditioner="jacobi")
    clamp_and_pull(box, sim, 1e-2)
    s = sim.step(spent_ms=2e5)
    assert s["iterations"] == 1 and s["budget_exhausted"]
    for _ in range(50):
        if sim.step()["info"] == "success":
            break
    assert sim.last_stats["info"] == "success"


def test_fem_statistics_budget_and_errors(box):
    # Jacobi: the cap of 3 iterations must stop the solve (Cholesky would converge first).
    sim = incise.FemSimulation(box, {1: incise.Material(1e5, 0.45)}, kind="corotational",
                               tolerance=1e-14, max_iterations=3, preconditioner="jacobi")
    with pytest.raises(incise.InvalidArgument):
        sim.step()  # nothing fixed: rigid modes
    clamp_and_pull(box, sim, 1e-2)
    s = sim.step()
    assert s["info"] == "no_convergence" and s["iterations"] == 3
    assert sim.last_stats == s
    with pytest.raises(incise.InvalidArgument, match="vertex 100000 is not a live vertex"):
        sim.fix(100000)
    with pytest.raises(incise.InvalidArgument, match="spent_ms"):
        sim.step(spent_ms=-1)
    with pytest.raises(incise.InvalidArgument, match="kind: unknown value 'quadratic'"):
        incise.FemSimulation(box, kind="quadratic")
    with pytest.raises(incise.InvalidArgument, match="poisson"):
        incise.FemSimulation(box, incise.Material(1e5, 0.5))
    # A relative residual of 1 or more is met by zero displacement: refused, not "converged".
    for tol in (1.0, 2.0):
        with pytest.raises(incise.InvalidArgument, match=r"tolerance: expected a relative residual in \(0, 1\)"):
            incise.FemSimulation(box, tolerance=tol)


def test_fem_keeps_its_mesh_alive():
    sim = incise.FemSimulation(incise.generate_box(1.0, 2), incise.Material(1e5, 0.0), tolerance=1e-12)
    gc.collect()  # the temporary mesh must survive: the simulation reads it every step
    sim.fix(range(27))
    assert sim.step()["info"] == "success"
    assert sim.displacement.shape == (27, 3) and not sim.displacement.any()


def test_springs_fall_freely_under_gravity(box):
    # No constraints: internal forces vanish for a rigid translation, so every particle follows
    # symplectic Euler exactly: x_n = g dt^2 n (n + 1) / 2.
    sim = incise.SpringSimulation(box, incise.Material(1e4, 0.3, 1000))
    g, dt, n = np.array([0, 0, -9.81]), 1e-4, 20
    sim.set_gravity(g)
    for _ in range(n):
        st = sim.step(dt)
        assert not st["stable_step_exceeded"]
    assert np.allclose(sim.displacement, g * dt * dt * n * (n + 1) / 2, rtol=1e-9, atol=1e-15)
    assert sim.num_springs > 0
    assert 0 < sim.stable_time_step() < 1
    with pytest.raises(incise.InvalidArgument, match="integrator"):
        sim.step(dt, "leapfrog")


def test_springs_fixed_vertices_stay(box):
    sim = incise.SpringSimulation(box, incise.Material(1e4, 0.3), damping=5.0)
    fixed = np.nonzero(box.points[:, 0] == 0)[0]
    sim.fix(fixed)
    sim.set_gravity((0, 0, -9.81))
    for _ in range(50):
        sim.step(sim.stable_time_step() * 0.5)
    assert np.array_equal(sim.positions[fixed], box.points[fixed])
    assert sim.displacement[:, 2].min() < 0


def test_springs_estimated_stable_step_and_initial_state(box):
    # The estimate from the fastest mode (docs/solver.md#spring-stable-step) is tighter than
    # Gershgorin's bound at rest, never below it there; half of it holds undamped.
    sim = incise.SpringSimulation(box, incise.Material(1e4, 0.3, 1000), damping=0.0)
    sim.fix(np.nonzero(box.points[:, 0] == 0)[0])
    bound, est = sim.stable_time_step(), sim.estimated_stable_time_step()
    assert bound <= est < 5 * bound
    assert sim.estimated_stable_time_step("implicit-euler") == np.inf
    with pytest.raises(incise.InvalidArgument, match="at least 2 iterations"):
        sim.estimated_stable_time_step("symplectic-euler", 1)
    # Initial conditions: a rigid velocity moves the free body rigidly; positions read back.
    free = incise.SpringSimulation(box, incise.Material(1e4, 0.3, 1000), damping=0.0)
    moved = box.points + np.array([0.0, 0.0, 0.5])
    free.set_positions(moved)
    assert np.array_equal(free.positions, moved)
    free.set_velocities(np.tile([1.0, 0.0, 0.0], (box.vertex_capacity, 1)))
    free.step(0.5 * est)
    assert np.allclose(free.positions, moved + [0.5 * est, 0, 0], rtol=0, atol=1e-12)
    with pytest.raises(incise.InvalidArgument, match="set_positions"):
        free.set_positions(np.zeros((3, 3)))


def test_scene_file(source_dir, tmp_path):
    beam = str(source_dir / "samples" / "scenes" / "beam.json")
    summary = incise.run_scene(beam, str(tmp_path / "out"), frames=2)
    assert summary["frames"] == 2 and summary["max_displacement"] > 0
    assert (tmp_path / "out" / summary["files"][0]).exists()
    mesh, sim = incise.simulation_from_scene(beam)
    assert isinstance(sim, incise.FemSimulation)
    tip = incise.vertices_in_box(mesh, (0.1199, -1, -1), (1, 1, 1))
    sim.set_force(tip, (0, 0, -0.2 / len(tip)))
    s = sim.step()
    assert s["info"] == "success"
    assert sim.displacement[tip, 2].max() < 0
    # A springs scene: its springs key reaches the model (simulation_from_scene builds it).
    springs = tmp_path / "springs.json"
    text = (source_dir / "samples" / "scenes" / "beam.json").read_text()
    text = text.replace('"model": "fem-corotational",', '"model": "springs", "springs": {"connectivity": "edges", '
                        '"volume": "tet"},').replace('"formulation": "nodal-averaged",', "")
    springs.write_text(text.replace('"beam.vtu"', '"' + str(source_dir / "samples" / "scenes" / "beam.vtu") + '"'))
    scene = incise.load_scene(str(springs))
    assert scene.springs["across_faces"] is False and scene.springs["nodal_volume"] is False
    mesh, sim = incise.simulation_from_scene(str(springs))
    assert isinstance(sim, incise.SpringSimulation)
    assert sim.num_springs == incise.SpringSimulation(mesh, across_faces=False).num_springs
    assert incise.load_scene(beam).springs["across_faces"] is True  # the default connectivity
    bad = tmp_path / "bad.json"
    bad.write_text('{"mesh": "x.vtu", "solver": {"tolerance": -1}}')
    with pytest.raises(incise.IoError, match="bad.json"):
        incise.load_scene(str(bad))


def test_fem_follows_mesh_edits_locally(box):
    young, d = 2e5, 1e-3
    sim = incise.FemSimulation(box, incise.Material(young=young, poisson=0.0), tolerance=1e-12)
    clamp_and_pull(box, sim, d)
    sim.step()
    a, b = box.tets[0][:2]
    v_edge = box.split_edge(a, b, 0.3)
    v_tet = box.split_tet(box.tet_ids[-1])
    assert box.has_pending_change
    change = box.take_change()
    assert [o[0] for o in change.added_vertices] == [v_edge, v_tet]
    assert len(change.added_tets) > len(change.removed_tets) > 0
    box.validate(check_manifold_boundary=True)
    sim.apply(change)
    x = box.points[:, 0]
    # new vertices start from the interpolated displacement, which is exact for a linear field
    assert np.allclose(sim.displacement[[v_edge, v_tet], 0], d * x[[v_edge, v_tet]], atol=1e-12)
    s = sim.step()
    assert s["info"] == "success"
    assert np.allclose(sim.displacement[:, 0], d * x, atol=1e-12)
    assert incise.TetMesh().num_tets == 0
    with pytest.raises(incise.InvalidArgument, match="tet 99999 is not a live tet"):
        box.split_tet(99999)


def test_springs_follow_mesh_edits(box):
    sim = incise.SpringSimulation(box, incise.Material(1e4, 0.3))
    sim.fix(np.nonzero(box.points[:, 0] == 0)[0])
    sim.set_gravity((0, 0, -9.81))
    for _ in range(5):
        sim.step(1e-4)
    before = sim.positions
    corners = box.tets[0]
    v = box.split_tet(box.tet_ids[0])  # at the centroid
    sim.apply(box.take_change())
    after = sim.positions
    assert after.shape == (box.vertex_capacity, 3)
    assert np.array_equal(after[: len(before)], before)  # old particles untouched
    assert np.allclose(after[v], before[corners].mean(axis=0), rtol=0, atol=1e-15)  # interpolated, deformed


@pytest.mark.parametrize("preconditioner", ["none", "jacobi", "block-jacobi", "cholesky", "amg"])
def test_every_preconditioner_reaches_the_same_answer(box, preconditioner):
    sim = incise.FemSimulation(box, incise.Material(young=1e5, poisson=0.3), preconditioner=preconditioner,
                               tolerance=1e-10)
    clamp_and_pull(box, sim, 1e-3)
    assert sim.step()["info"] == "success"
    ref = incise.FemSimulation(box, incise.Material(young=1e5, poisson=0.3), method="direct")
    clamp_and_pull(box, ref, 1e-3)
    ref.step()
    assert np.allclose(sim.displacement, ref.displacement, atol=1e-9)
    with pytest.raises(incise.InvalidArgument, match="preconditioner"):
        incise.FemSimulation(box, incise.Material(), preconditioner="ilu")


# Issue 18 section 3: what the CLI and scenes refuse, the simulations refuse too.
def test_material_dict_must_cover_the_mesh_labels(box):
    with pytest.raises(incise.InvalidArgument, match="no material for region label 1"):
        incise.FemSimulation(box, {7: incise.Material(young=2e6)})
    with pytest.raises(incise.InvalidArgument, match="no material for region label 1"):
        incise.SpringSimulation(box, {7: incise.Material(young=2e6)})
    incise.FemSimulation(box, {7: incise.Material(), "*": incise.Material(young=2e6)})
    incise.FemSimulation(box, {1: incise.Material(young=2e6)})


def test_simulation_arguments_get_incise_errors(box):
    with pytest.raises(incise.InvalidArgument, match=r"materials\[1\]: expected a Material, got str"):
        incise.FemSimulation(box, {1: "soft"})
    with pytest.raises(incise.InvalidArgument, match="materials: key 1.5: expected an integer region label"):
        incise.FemSimulation(box, {1.5: incise.Material()})
    with pytest.raises(incise.InvalidArgument, match="FemSimulation: mesh: expected an incise.TetMesh, got str"):
        incise.FemSimulation("box.msh")
    with pytest.raises(incise.InvalidArgument, match="volume_term: expected True or False, got -1"):
        incise.SpringSimulation(box, volume_term=-1)
    incise.SpringSimulation(box, volume_term=np.bool_(False))


def test_loads_and_constraints_must_be_finite(box):
    fem = incise.FemSimulation(box)
    with pytest.raises(incise.InvalidArgument, match="force: expected 3 finite numbers"):
        fem.set_force(0, (0, 0, np.nan))
    with pytest.raises(incise.InvalidArgument, match="displacement: expected 3 finite numbers"):
        fem.prescribe(0, (np.inf, 0, 0))
    with pytest.raises(incise.InvalidArgument, match="vertex ids: expected integers, got float64"):
        fem.fix([0.0, 1.5])
    springs = incise.SpringSimulation(box)
    with pytest.raises(incise.InvalidArgument, match="position: expected 3 finite numbers"):
        springs.prescribe(0, (0, np.nan, 0))
    with pytest.raises(incise.InvalidArgument, match="force: expected real numbers, got complex128"):
        springs.set_force(0, (1j, 0, 0))


@pytest.mark.parametrize("frames", [-3, -1, 0, 2.0])
def test_run_scene_frames_as_the_cli(source_dir, tmp_path, frames):
    beam = str(source_dir / "samples" / "scenes" / "beam.json")
    with pytest.raises(incise.InvalidArgument, match="run_scene: frames"):
        incise.run_scene(beam, str(tmp_path / "out"), frames=frames)
    assert not (tmp_path / "out").exists()


def squeezed_box(mesh, formulation, nu):
    """A 2x1x1 box on three symmetry rollers, its end x = 2 prescribed 0.02 inwards, solved directly."""
    x = mesh.points
    sim = incise.FemSimulation(mesh, incise.Material(1e3, nu), formulation=formulation, method="direct")
    sim.constrain(np.nonzero(x[:, 0] == 0)[0], "x")
    sim.constrain(np.nonzero(x[:, 1] == 0)[0], "y")
    sim.constrain(np.nonzero(x[:, 2] == 0)[0], "z")
    sim.constrain(np.nonzero(x[:, 0] == 2)[0], "x", (-0.02, 0, 0))
    assert sim.step()["info"] == "success"
    return sim


def test_formulations_rollers_and_incompressible_pressure():
    # A 2x1x1 box on three symmetry rollers, squeezed along x by a prescribed end: standard tets
    # at nu = 0.4999 lock (the end needs a far larger force), nodal-averaged and mixed do not, and
    # the mixed formulation takes nu = 0.5 exactly and keeps the volume.
    mesh = incise.generate_box((2.0, 1.0, 1.0), (4, 2, 2))
    x = mesh.points

    def squeezed(formulation, nu):
        return squeezed_box(mesh, formulation, nu)

    for formulation in ("mixed", "mixed-edge-smoothed"):
        mixed = squeezed(formulation, 0.5)
        u = mixed.displacement
        # Uniaxial compression of an incompressible body: the lateral faces move out by half the strain.
        assert np.allclose(u[:, 0], -0.01 * x[:, 0], atol=1e-9)
        assert np.allclose(u[:, 1], 0.005 * x[:, 1], atol=1e-9)
        assert np.allclose(u[:, 2], 0.005 * x[:, 2], atol=1e-9)
        assert mixed.pressure.shape == (mesh.vertex_capacity,)
        assert np.all(mixed.pressure == pytest.approx(mixed.pressure[0]))  # uniform stress state
    for f in ("standard", "nodal-averaged", "edge-smoothed"):
        assert squeezed(f, 0.3).pressure is None
    with pytest.raises(incise.InvalidArgument, match="poisson"):
        incise.FemSimulation(mesh, incise.Material(1e3, 0.5), formulation="nodal-averaged")
    with pytest.raises(incise.InvalidArgument, match="formulation: expected"):
        incise.FemSimulation(mesh, formulation="b-bar")
    sim = incise.FemSimulation(mesh)
    with pytest.raises(incise.InvalidArgument, match="components"):
        sim.constrain([0], "xq")


def test_quadratic_formulations_reproduce_uniaxial_compression_at_their_mid_edge_nodes():
    # The same squeezed box on 10-node tets: the linear field is exact at every node, mid-edge
    # ones too, and Taylor-Hood ("mixed-quadratic") takes nu = 0.5 with a uniform pressure.
    mesh = incise.generate_box((2.0, 1.0, 1.0), (4, 2, 2))
    x = mesh.points
    for formulation, nu in (("quadratic", 0.3), ("mixed-quadratic", 0.5)):
        sim = squeezed_box(mesh, formulation, nu)
        lateral = nu * 0.01
        expected = np.column_stack([-0.01 * x[:, 0], lateral * x[:, 1], lateral * x[:, 2]])
        assert np.allclose(sim.displacement, expected, atol=1e-9)
        edges, u_mid = sim.mid_edge_nodes
        mid = 0.5 * (x[edges[:, 0]] + x[edges[:, 1]])
        assert np.allclose(u_mid, np.column_stack([-0.01 * mid[:, 0], lateral * mid[:, 1], lateral * mid[:, 2]]), atol=1e-9)
        if formulation == "mixed-quadratic":
            assert np.all(sim.pressure == pytest.approx(sim.pressure[0]))
        else:
            assert sim.pressure is None
    assert incise.FemSimulation(mesh).mid_edge_nodes is None
    with pytest.raises(incise.InvalidArgument, match="poisson"):
        incise.FemSimulation(mesh, incise.Material(1e3, 0.5), formulation="quadratic")


def test_run_scene_into_a_directory_behaves_like_incise_simulate(tmp_path):
    scene = tmp_path / "s.json"
    body = """{
      "mesh": {"generate": "box", "size": [4, 1, 1], "cells": [8, 2, 2]},
      "model": "fem-linear",
      "materials": {"*": {"young": 1e9, "poisson": 0.3}},
      "fixed": [{"box": [-0.01, -0.01, -0.01, 0.01, 1.01, 1.01]}],
      "loads": [{"type": "gravity", "g": [0, 0, -9.81]}],
      "time": {"frames": %d}%s
    }"""
    scene.write_text(body % (5, ""))
    # A directory of the user's files is refused and kept, also files named like a run's.
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "stats.csv").write_text("mine\n")
    (mine / "notes.txt").write_text("mine\n")
    with pytest.raises(incise.IoError, match="did not write"):
        incise.run_scene(str(scene), str(mine))
    assert sorted(p.name for p in mine.iterdir()) == ["notes.txt", "stats.csv"]
    assert (mine / "stats.csv").read_text() == "mine\n"
    # A run that fails at frame 2 after a 5-frame run leaves the 5-frame run whole.
    out = tmp_path / "out"
    assert incise.run_scene(str(scene), str(out))["frames"] == 5
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    breaks = tmp_path / "breaks.json"
    breaks.write_text(body % (4, """, "fragments": "error",
      "cuts": [{"blade": [[2.03, -0.5, 1.5], [2.03, 1.5, 1.5]], "sweep": [0, 0, -2], "from_frame": 2, "to_frame": 2}]"""))
    with pytest.raises(incise.Error, match="keeps the earlier run"):
        incise.run_scene(str(breaks), str(out))
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_apply_refuses_another_meshs_change_a_repeat_and_a_skip():
    # A change names ids of its own mesh as it is after that change: applied to another mesh's
    # simulation, or after the mesh moved on, it once crashed the process (malloc corruption, a
    # segfault in the springs). Refused now, before the simulation touches its data.
    mesh = incise.generate_box((1.0, 1.0, 1.0), (3, 3, 3))
    other = incise.generate_box((1.0, 1.0, 1.0), (4, 4, 4))
    mesh.take_change()
    other.take_change()
    fem = incise.FemSimulation(mesh, incise.Material(1e4, 0.3))
    springs = incise.SpringSimulation(mesh, incise.Material(1e4, 0.3))
    foreign = incise.Cutter(other).cut_plane((0.52, 0.5, 0.5), (1, 0, 0))["change"]
    for sim in (fem, springs):
        with pytest.raises(incise.InvalidArgument, match="another mesh's change"):
            sim.apply(foreign)
    cutter = incise.Cutter(mesh)
    first = cutter.cut_plane((0.52, 0.5, 0.5), (1, 0, 0))["change"]
    fem.apply(first)
    with pytest.raises(incise.InvalidArgument, match="applied already"):
        fem.apply(first)
    second = cutter.cut_plane((0.5, 0.37, 0.5), (0, 1, 0))["change"]
    with pytest.raises(incise.InvalidArgument, match="expected the mesh's change #1, got #2"):
        springs.apply(second)  # the first skipped
    with pytest.raises(incise.InvalidArgument, match="is not the mesh's latest"):
        springs.apply(first)  # the mesh has moved past it
    fem.apply(second)
    assert fem.displacement.shape == (mesh.vertex_capacity, 3)
    assert np.isfinite(fem.displacement).all()


def test_simulate_interrupted_by_a_signal_stops_cleanly(tmp_path):
    # Ctrl-C (SIGINT), SIGTERM or SIGHUP: the run stops before its next frame, says so, exits 1,
    # and leaves no hidden run directory beside DIR (one was 481 MB after Ctrl-C at 3 s).
    import os
    import signal
    import subprocess
    exe = os.environ.get("INCISE_EXE")
    if not exe:
        pytest.skip("INCISE_EXE not set (the incise executable)")
    scene = tmp_path / "long.json"
    scene.write_text("""{
      "mesh": {"generate": "box", "size": [1, 1, 1], "cells": [2, 2, 2]},
      "model": "fem-linear",
      "materials": {"*": {"young": 1e4, "poisson": 0.3}},
      "fixed": [{"box": [-0.01, -0.01, -0.01, 0.01, 1.01, 1.01]}],
      "loads": [{"type": "gravity", "g": [0, 0, -9.81]}],
      "time": {"frames": 100000000},
      "output": {"every": 1000000}
    }""")
    for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        out = tmp_path / f"out_{int(sig)}"
        p = subprocess.Popen([exe, "simulate", str(scene), "-o", str(out)], stderr=subprocess.PIPE, text=True)
        assert "frame 0" in p.stderr.readline()  # running
        p.send_signal(sig)
        err = p.stderr.read()
        assert p.wait(timeout=60) == 1
        assert f"interrupted by signal {int(sig)}" in err
        assert [q.name for q in tmp_path.iterdir() if q.name.startswith(".")] == []


def test_springs_step_that_blows_up_raises_and_keeps_the_state(box):
    # dt far past the stable step: the symplectic step overflows within a few steps; the step
    # that does raises, and the state before it is kept (finite), not NaN.
    s = incise.SpringSimulation(box)
    s.set_gravity((0, 0, -9.81))
    with pytest.raises(incise.Error, match="the state became non-finite .* times the stable time step"):
        for _ in range(50):
            s.step(1e6)
    assert np.isfinite(s.positions).all() and np.isfinite(s.velocities).all()


def test_run_scene_warns_of_a_cut_that_met_nothing(tmp_path):
    scene = tmp_path / "miss.json"
    scene.write_text('{"mesh": {"generate": "box", "size": [4, 1, 1], "cells": [8, 2, 2]}, "model": "fem-linear",'
                     ' "materials": {"*": {"young": 1e4, "poisson": 0.3, "density": 1}},'
                     ' "fixed": [{"box": [-0.01, -1, -1, 0.01, 2, 2]}], "loads": [{"type": "gravity", "g": [0, 0, -1]}],'
                     ' "time": {"frames": 4}, "cuts": [{"blade": [[2.03, -0.5, 1.6], [2.03, 1.5, 1.6]],'
                     ' "sweep": [0, 0, -0.3], "from_frame": 1, "to_frame": 2}]}')
    summary = incise.run_scene(str(scene), str(tmp_path / "run"))
    assert len(summary["warnings"]) == 1 and "cuts[0] (frames 1-2) cut nothing" in summary["warnings"][0]


def test_material_out_of_range_and_cell_data_by_tet_id(box, tmp_path):
    with pytest.raises(incise.InvalidArgument, match="Material.poisson"):
        incise.Material(poisson=0.6)
    assert incise.Material(poisson=0.5).poisson == 0.5  # the mixed formulation takes it
    with pytest.raises(incise.InvalidArgument, match="expected one row per tet id slot, .* rows \\(mesh.tet_capacity"):
        incise.write(box, str(tmp_path / "c.vtu"), cell_data={"x": np.zeros(box.num_tets + 1)})


def test_standard_tets_near_incompressible_warn(tmp_path):
    scene = tmp_path / "lock.json"
    scene.write_text('{"mesh": {"generate": "box", "size": [4, 1, 1], "cells": [4, 1, 1]}, "model": "fem-linear",'
                     ' "materials": {"*": {"young": 1e4, "poisson": 0.47}},'
                     ' "fixed": [{"box": [-0.01, -1, -1, 0.01, 2, 2]}], "loads": [{"type": "gravity", "g": [0, 0, -1]}],'
                     ' "time": {"frames": 1}}')
    summary = incise.run_scene(str(scene), str(tmp_path / "run"))
    assert any("standard tets at Poisson's ratio 0.47 lock" in w for w in summary["warnings"])
    scene.write_text(scene.read_text().replace('"model"', '"formulation": "nodal-averaged", "model"'))
    assert incise.run_scene(str(scene), str(tmp_path / "run2"))["warnings"] == []


def test_fem_inversion_barrier_holds_a_pushed_box():
    # The C++ test's box (tests/sim/test_inversion_barrier.cpp): the top's middle vertex pushed
    # down by a point force inverts tets at the plain corotational equilibrium; held, none.
    mesh = incise.generate_box((2, 2, 2), (2, 2, 2))

    def inverted(**kw):
        sim = incise.FemSimulation(mesh, incise.Material(1000, 0.3), kind="corotational", tolerance=1e-10,
                                   nonlinear_iterations=2, **kw)
        p = mesh.points
        sim.fix(np.nonzero(p[:, 2] == 0)[0])
        top = int(np.nonzero(np.all(np.isclose(p, (1, 1, 2)), axis=1))[0][0])
        sim.set_force(top, (0, 0, -2000))
        for _ in range(6):
            sim.step()
        x = sim.positions
        t = mesh.tets
        d = np.einsum("ij,ij->i", x[t[:, 1]] - x[t[:, 0]], np.cross(x[t[:, 2]] - x[t[:, 0]], x[t[:, 3]] - x[t[:, 0]]))
        return int((d <= 0).sum()), sim

    assert inverted()[0] > 0
    n, sim = inverted(inversion_barrier=0.2)
    assert n == 0 and sim.barrier_tets > 0
    with pytest.raises(incise.InvalidArgument):
        incise.FemSimulation(mesh, incise.Material(1000, 0.3), inversion_barrier=0.2)  # linear: refused


def test_springs_nodal_volume_term_sags_its_own_way(box):
    # The volume term per tet or averaged at the vertices (docs/solver.md#spring-volume-terms):
    # a clamped bar sagging under gravity settles to different, finite shapes.
    def sag(**kw):
        sim = incise.SpringSimulation(box, incise.Material(1e5, 0.45, 1000), damping=20.0, **kw)
        sim.fix(np.nonzero(box.points[:, 0] == 0)[0])
        sim.set_gravity((0, 0, -9.81))
        for _ in range(40):
            sim.step(0.01, "implicit-euler")
        return sim.displacement[:, 2].min()

    per_tet, nodal = sag(nodal_volume=False), sag(nodal_volume=True)  # the default: nodal (a blend)
    assert nodal == sag()
    assert np.isfinite(nodal) and nodal < 0 and per_tet < 0
    assert nodal != per_tet
    with pytest.raises(incise.InvalidArgument, match="nodal_volume: expected True or False"):
        incise.SpringSimulation(box, nodal_volume=1)
    # Spring constants fitted to each tet's FEM stiffness (docs/solver.md#spring-stiffness).
    fitted = sag(stiffness="fitted")
    assert np.isfinite(fitted) and fitted < 0 and fitted != per_tet
    with pytest.raises(incise.InvalidArgument, match='stiffness: expected van-gelder or fitted, got "lloyd"'):
        incise.SpringSimulation(box, stiffness="lloyd")
    # Springs across the interior faces too (docs/solver.md#spring-connectivity): more springs,
    # another sag; not with fitted constants.
    edges = sag(across_faces=False)  # the default: across faces too
    assert np.isfinite(edges) and edges < 0 and edges != nodal
    assert incise.SpringSimulation(box).num_springs > incise.SpringSimulation(box, across_faces=False).num_springs
    with pytest.raises(incise.InvalidArgument, match="van-gelder stiffness, not fitted"):
        incise.SpringSimulation(box, across_faces=True, stiffness="fitted")
    with pytest.raises(incise.InvalidArgument, match="face_share"):
        incise.SpringSimulation(box, across_faces=True, face_share=1.5)
    # The nodal term blended with the per-tet one (docs/solver.md#spring-volume-terms).
    blend = sag(nodal_volume=True, nodal_share=0.5)
    assert np.isfinite(blend) and blend < 0 and blend not in (per_tet, nodal)
    assert sag(nodal_volume=True, nodal_share=0.0) == pytest.approx(per_tet, rel=1e-9)
    with pytest.raises(incise.InvalidArgument, match="nodal_share"):
        incise.SpringSimulation(box, nodal_volume=True, nodal_share=-0.5)
    # The inversion guard (docs/solver.md#spring-volume-terms) adds nothing where no tet is
    # squeezed below its ratio: a sag is such a load.
    assert sag(nodal_share=1.0, inversion_guard=0.3) == sag(nodal_share=1.0)
    with pytest.raises(incise.InvalidArgument, match="inversion_guard: expected a volume ratio"):
        incise.SpringSimulation(box, inversion_guard=1.0)
    with pytest.raises(incise.InvalidArgument, match="inversion_guard: acts beside a volume term"):
        incise.SpringSimulation(box, volume_term=False, inversion_guard=0.5)


def test_springs_viscosity_and_stiffening(box):
    # Stiffening springs sag less than Hookean ones under the same load, and viscous ones settle
    # where the others do (docs/solver.md#spring-options).

    def sag(**kw):
        s = incise.SpringSimulation(box, incise.Material(1e4, 0.3, 1000), damping=20.0, **kw)
        s.fix(np.nonzero(box.points[:, 0] == 0)[0])
        s.set_gravity((0, 0, -9.81 * 5))
        for _ in range(60):
            s.step(0.01, "implicit-euler")
        return -s.displacement[:, 2].min()

    hooke, fung, viscous = sag(), sag(stiffening=5.0), sag(viscosity=1e-3)
    assert 0 < fung < hooke
    assert viscous == pytest.approx(hooke, rel=1e-3)
    with pytest.raises(incise.InvalidArgument, match="stiffening"):
        incise.SpringSimulation(box, stiffening=-1.0)
