"""incise.improve / improve_local: the `incise improve --json` report, invariants kept, and the
change applied to a simulation."""
import numpy as np
import pytest

import incise


def jittered_box(seed=3, amount=0.3):
    m = incise.generate_box((1.0, 1.0, 1.0), (5, 5, 5))
    pts, tets = m.points.copy(), m.tets
    rng = np.random.default_rng(seed)
    inner = np.all((pts > 1e-9) & (pts < 1 - 1e-9), axis=1)
    pts[inner] += rng.uniform(-amount, amount, size=(inner.sum(), 3)) * 0.2
    return incise.TetMesh(pts, tets)


def test_improve_raises_the_worst_angle_and_keeps_volume():
    m = jittered_box()
    v0 = m.volume()
    r = incise.improve(m, time_limit=5)
    assert r["schema"] == "incise.improve/1"
    assert r["after"]["min_dihedral"] >= r["before"]["min_dihedral"]
    assert r["after"]["min_dihedral"] > r["before"]["min_dihedral"] + 1
    assert r["after"]["tets"] == m.num_tets
    assert m.volume() == pytest.approx(v0, rel=1e-9)
    m.validate(check_manifold_boundary=True)
    assert not r["change"].empty()


def test_local_pass_after_an_edit_follows_into_fem():
    m = jittered_box(seed=5)
    fem = incise.FemSimulation(m, incise.Material(young=1e4, poisson=0.3))
    fem.fix(np.nonzero(m.points[:, 0] < 1e-9)[0])
    fem.step()
    seeds = m.tet_ids[:20]
    r = incise.improve_local(m, seeds, max_work=200)
    fem.apply(r["change"])
    assert fem.step()["info"] == "success"
    m.validate(check_manifold_boundary=True)
    with pytest.raises(incise.InvalidArgument, match="seed"):
        incise.improve_local(m, [10**9])


def test_improve_refuses_a_mesh_with_pending_edits():
    m = incise.generate_box((1.0, 1.0, 1.0), (2, 2, 2))
    m.split_tet(int(m.tet_ids[0]))
    with pytest.raises(incise.InvalidArgument, match="take_change"):
        incise.improve(m)


def test_improve_without_flips_keeps_the_connectivity():
    # Like `incise improve --no-flips`: smoothing only, so no contraction either. A plane cut
    # with no snapping leaves tiny edges that contraction removes when flips are on.
    def cut_box():
        m = jittered_box()
        incise.Cutter(m, snap=0.0, improve=False).cut_plane((0.5, 0.5, 0.503), (0.02, 0.01, 1.0))
        return m
    m = cut_box()
    tets0 = np.sort(np.sort(m.tets, axis=1), axis=0)
    r = incise.improve(m, time_limit=5, flips=False)
    assert r["operations"]["contractions"] == 0
    assert np.array_equal(np.sort(np.sort(m.tets, axis=1), axis=0), tets0)
    assert incise.improve(cut_box(), time_limit=5)["operations"]["contractions"] > 0


def test_improve_keywords_for_multi_face_removal_and_the_radius_ratio_floor(source_dir):
    # multi_face=False is `--no-multi-face`: the sample elephant gets discs of three faces or
    # more removed by default (47), none without.
    elephant = str(source_dir / "samples" / "elephant.msh")
    assert incise.improve(incise.read(elephant), time_limit=5)["operations"]["multi_face_removals"] > 0
    r = incise.improve(incise.read(elephant), time_limit=5, multi_face=False)
    assert r["operations"]["multi_face_removals"] == 0
    # With insertion the floor bounds how far the smallest radius ratio may drop.
    m = jittered_box()
    r = incise.improve(m, time_limit=5, insert=True, radius_ratio_floor=0.3)
    assert r["after"]["min_radius_ratio"] >= min(r["before"]["min_radius_ratio"], 0.3) - 1e-12
    with pytest.raises(incise.InvalidArgument, match="radius_ratio_floor"):
        incise.improve(jittered_box(), radius_ratio_floor=0.0)


# Issue 18 section 3: the options `incise improve` refuses, improve() refuses, same rule.
@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"target_dihedral": 200}, "0 < target_dihedral < 70.5 < target_max_dihedral < 180"),
        ({"target_max_dihedral": float("nan")}, "0 < target_dihedral < 70.5"),
        ({"max_growth": 0}, "max_growth must be at least 1"),
        ({"radius_ratio_floor": 0}, r"radius_ratio_floor must be in \(0, 1\]"),
        ({"feature_angle": 400}, r"feature_angle: 400 is out of range \[0, 180\]"),
        ({"time_limit": -1}, r"time_limit: -1 is out of range \[0, 1e\+06\]"),
        ({"time_limit": float("inf")}, "time_limit: 'inf': expected a finite number"),
        ({"volume_tolerance": 2}, r"volume_tolerance: 2 is out of range \[0, 1\]"),
    ],
)
def test_improve_refuses_what_the_cli_refuses(kwargs, message):
    m = incise.generate_box(1.0, 2)
    with pytest.raises(incise.InvalidArgument, match=message):
        incise.improve(m, **kwargs)
    assert not m.has_pending_change


def test_improve_local_refuses_bad_rings_budget_and_seeds():
    m = incise.generate_box(1.0, 2)
    with pytest.raises(incise.InvalidArgument, match="rings: expected an integer >= 0"):
        incise.improve_local(m, [0], rings=-1)
    with pytest.raises(incise.InvalidArgument, match="budget_ms: -5 is out of range"):
        incise.improve_local(m, [0], budget_ms=-5)
    with pytest.raises(incise.InvalidArgument, match="max_work: expected an integer >= 0"):
        incise.improve_local(m, [0], max_work=-1)
    with pytest.raises(incise.InvalidArgument, match="seeds: expected integers"):
        incise.improve_local(m, [0.5])
    with pytest.raises(incise.InvalidArgument, match="seed tet 100000 is not a live tet"):
        incise.improve_local(m, [100000])


def test_improve_keeps_label_volumes_within_volume_tolerance(source_dir):
    # The sample liver is curved: sliding on it without a limit moves its volume by over 0.1%.
    liver = str(source_dir / "samples" / "liver.msh")

    def volumes(m):
        vols = {}
        pts, tets, labels = m.points, m.tets, m.labels
        a, b, c, d = (pts[tets[:, k]] for k in range(4))
        v = np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) / 6
        for lab in np.unique(labels):
            vols[int(lab)] = float(v[labels == lab].sum())
        return vols

    m = incise.read(liver)
    before = volumes(m)
    r = incise.improve(m, time_limit=10)
    after = volumes(m)
    moved = max(abs(after[k] - v) / v for k, v in before.items())
    assert moved <= 1e-4 * (1 + 1e-9)
    assert r["label_volume_change"] == pytest.approx(moved, abs=1e-12)
    loose = incise.read(liver)
    incise.improve(loose, time_limit=10, volume_tolerance=1.0)
    after = volumes(loose)
    assert max(abs(after[k] - v) / v for k, v in before.items()) > 1e-3


def test_improve_edge_stars_keyword():
    # Three tets around the boundary edge along z, its 120 degrees split 10 / 55 / 55: with
    # insertion the 10-degree tet is lifted (a vertex inside all three, where the edge stars
    # start a cavity); edge_stars=False is `--no-edge-stars`, and the report is the same dict.
    deg = np.radians([0.0, 10.0, 65.0, 120.0])
    pts = np.vstack([[0, 0, 0], [0, 0, 1], np.column_stack([np.cos(deg), np.sin(deg), np.full(4, 0.5)])])
    tets = np.array([[0, 1, 2 + i, 3 + i] for i in range(3)])
    r = incise.improve(incise.TetMesh(pts, tets), insert=True, max_growth=10, fixed_boundary=True)
    assert r["before"]["min_dihedral"] < 10.5
    assert r["after"]["min_dihedral"] > 15
    r = incise.improve(incise.TetMesh(pts, tets), insert=True, max_growth=10, fixed_boundary=True, edge_stars=False)
    assert r["after"]["min_dihedral"] >= r["before"]["min_dihedral"]  # never worse, either way
    with pytest.raises(TypeError):
        incise.improve(incise.TetMesh(pts, tets), edge_star=True)


def test_improve_max_work_stops_after_that_many_operations():
    # max_work is `--max-work`: a pass limited by operations, not the clock, gives the same
    # mesh every run; the report counts the operations it spent.
    a, b, c = jittered_box(), jittered_box(), jittered_box()
    ra = incise.improve(a, time_limit=0, max_work=30)
    rb = incise.improve(b, time_limit=0, max_work=30)
    rc = incise.improve(c, time_limit=0)
    assert ra["budget_exhausted"] and ra["work"] >= 30
    assert rc["work"] > ra["work"]
    assert np.array_equal(a.points, b.points) and np.array_equal(a.tets, b.tets)
    assert rc["after"]["min_dihedral"] >= ra["after"]["min_dihedral"]
    with pytest.raises(incise.InvalidArgument):
        incise.improve(jittered_box(), max_work=-1)
