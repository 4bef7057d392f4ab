import numpy as np
import pytest

import incise
from conftest import signed_volumes


@pytest.mark.parametrize("cells", [(1, 1, 1), (3, 2, 5)])
@pytest.mark.parametrize("scale", [1e-8, 1.0, 1e8])
def test_box_arrays_agree_with_the_mesh(cells, scale):
    size = np.array([1.0, 2.0, 0.5]) * scale
    m = incise.generate_box(size, cells)
    n = int(np.prod(cells))
    assert m.num_tets == 6 * n
    assert m.num_vertices == int(np.prod(np.array(cells) + 1))
    assert m.points.shape == (m.num_vertices, 3) and m.points.dtype == np.float64
    assert m.tets.shape == (m.num_tets, 4)
    assert m.labels.shape == (m.num_tets,) and set(m.labels) == {1}
    vol = signed_volumes(m.points, m.tets)
    assert (vol > 0).all()  # positive orientation convention
    assert vol.sum() == pytest.approx(np.prod(size), rel=1e-12)
    assert m.volume() == pytest.approx(np.prod(size), rel=1e-12)
    m.validate(check_manifold_boundary=True)


def test_boundary_faces_are_closed_and_outward(box):
    faces, tags = box.boundary_faces()
    assert (tags == 1).all()  # surface tag
    edges = {}
    for f in faces:
        for k in range(3):
            e = (int(f[k]), int(f[(k + 1) % 3]))
            edges[e] = edges.get(e, 0) + 1
    # closed and consistently oriented: every directed edge has its reverse exactly once
    assert all(edges.get((b, a)) == 1 for (a, b) in edges)
    p = box.points
    centroid = p.mean(axis=0)
    a, b, c = p[faces[:, 0]], p[faces[:, 1]], p[faces[:, 2]]
    n = np.cross(b - a, c - a)
    assert (np.einsum("ij,ij->i", n, (a + b + c) / 3 - centroid) > 0).all()


def test_from_arrays_round_trip_and_reorientation(box):
    copy = incise.TetMesh(box.points, box.tets, box.labels + 1)
    assert np.array_equal(copy.points, box.points)
    assert np.array_equal(copy.tets, box.tets)
    assert (copy.labels == 2).all()
    inverted = incise.TetMesh([[0, 0, 0], [1, 0, 0], [0, 0, 1], [0, 1, 0]], [[0, 1, 2, 3]])
    assert inverted.volume() == pytest.approx(1 / 6)
    inverted.validate()


def test_from_arrays_errors():
    pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]
    with pytest.raises(incise.InvalidArgument, match="tet #0 references vertex 7 out of range"):
        incise.TetMesh(pts, [[0, 1, 2, 7]])
    with pytest.raises(incise.InvalidArgument, match="tets must be #T by 4"):
        incise.TetMesh(pts, [[0, 1, 2]])
    with pytest.raises(incise.InvalidArgument, match="one entry per tet"):
        incise.TetMesh(pts, [[0, 1, 2, 3]], labels=[1, 2])
    with pytest.raises(incise.Error, match="repeated|same four vertices"):
        incise.TetMesh(pts, [[0, 1, 2, 3], [0, 1, 3, 2]])


def test_from_arrays_refuses_overlapping_tets(box):
    # A tet spanning the box from its corner: it shares no face, only corners, with the others.
    p = box.points
    lo, hi = p.min(axis=0), p.max(axis=0)
    corner = lambda q: int(np.argmin(np.linalg.norm(p - q, axis=1)))
    span = [corner(lo), corner([hi[0], lo[1], lo[2]]), corner([lo[0], hi[1], lo[2]]), corner([lo[0], lo[1], hi[2]])]
    with pytest.raises(incise.Error, match=f"tet #{box.num_tets} overlaps tet #[0-9]+ \\(their interiors intersect\\)"):
        incise.TetMesh(p, np.vstack([box.tets, [span]]))
    # Moved out of the box, the same tet is accepted.
    moved = np.vstack([p, p[span] - [2 * (hi[0] - lo[0]), 0, 0]])
    n = len(p)
    extra = incise.TetMesh(moved, np.vstack([box.tets, [[n, n + 1, n + 2, n + 3]]]))
    assert extra.num_tets == box.num_tets + 1


def test_generator_errors_are_invalid_argument():
    with pytest.raises(incise.InvalidArgument):
        incise.generate_box((1, 1, 1), (0, 1, 1))
    assert issubclass(incise.InvalidArgument, incise.Error)
    assert issubclass(incise.Error, RuntimeError)


def test_ellipsoid_volume_converges():
    exact = 4 / 3 * np.pi * 1.0 * 0.5 * 0.25
    errors = [abs(incise.generate_ellipsoid((1.0, 0.5, 0.25), n).volume() - exact) for n in (2, 4, 8)]
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 0.02 * exact


def test_compact_maps_are_identity_on_a_fresh_mesh(box):
    vmap, tmap = box.compact()
    assert np.array_equal(vmap, np.arange(box.num_vertices))
    assert np.array_equal(tmap, np.arange(box.num_tets))


def test_compact_spatially_permutes_consistently():
    # A box read back with its vertices in reversed order: the curve's numbering maps every old
    # point and tet to its new id, and the mesh is the same.
    box = incise.generate_box((2.0, 1.0, 1.0), (4, 3, 2))
    pts, tets = box.points[::-1].copy(), (box.num_vertices - 1 - box.tets)
    m = incise.TetMesh(pts, tets)
    vmap, tmap = m.compact_spatially()
    assert sorted(vmap) == list(range(m.num_vertices)) and sorted(tmap) == list(range(m.num_tets))
    assert np.array_equal(m.points[vmap], pts)
    assert np.array_equal(m.tets[tmap], vmap[tets])
    assert m.volume() == pytest.approx(box.volume(), rel=1e-12)
    m.validate(check_manifold_boundary=True)


# Issue 18 section 3: the arrays get the checks a file gets, with incise's messages.
PTS = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_from_arrays_refuses_non_finite_points(bad):
    pts = np.array(PTS, dtype=float)
    pts[2, 1] = bad
    with pytest.raises(incise.InvalidArgument, match=r"non-finite point coordinate \(point 2\)"):
        incise.TetMesh(pts, [[0, 1, 2, 3]])


def test_from_arrays_refuses_float_indices_and_wide_labels():
    with pytest.raises(incise.InvalidArgument, match="tets: expected integers, got float64"):
        incise.TetMesh(PTS, [[0, 1, 2, 3.9]])
    with pytest.raises(incise.InvalidArgument, match="label 1099511627776 of tet #0 is out of range"):
        incise.TetMesh(PTS, [[0, 1, 2, 3]], labels=[2**40])
    with pytest.raises(incise.InvalidArgument, match="labels: expected integers"):
        incise.TetMesh(PTS, [[0, 1, 2, 3]], labels=[1.5])
    assert list(incise.TetMesh(PTS, np.array([[0, 1, 2, 3]], dtype=np.uint8), labels=[-(2**31)]).labels) == [-(2**31)]


def test_from_arrays_refuses_complex_and_string_points():
    with pytest.raises(incise.InvalidArgument, match="points: expected real numbers, got complex128"):
        incise.TetMesh(np.array(PTS, dtype=complex) + 1j, [[0, 1, 2, 3]])
    with pytest.raises(incise.InvalidArgument, match="points: expected real numbers"):
        incise.TetMesh([[str(x) for x in p] for p in PTS], [[0, 1, 2, 3]])


def test_split_tet_weights_must_sum_to_one():
    m = incise.TetMesh(PTS, [[0, 1, 2, 3]])
    with pytest.raises(incise.InvalidArgument, match="must sum to 1"):
        m.split_tet(0, (0.5, 0.5, 0.5, 0.5))
    assert m.num_tets == 1 and not m.has_pending_change
    m.split_tet(0, (0.1, 0.2, 0.3, 0.4))
    m.validate()


def test_generator_arguments_get_incise_errors():
    with pytest.raises(incise.InvalidArgument, match="cells: expected integers"):
        incise.generate_box(1.0, (1.5, 1, 1))
    with pytest.raises(incise.InvalidArgument, match="cells: expected an integer or 3 integers"):
        incise.generate_box(1.0, (1, 1))
    with pytest.raises(incise.InvalidArgument, match="size: expected 3 finite numbers"):
        incise.generate_box((1, np.nan, 1), 1)


def test_ids_past_32_bits_and_degenerate_edits_are_refused(box):
    # 2**32 would wrap onto vertex 0, which is alive.
    assert not box.is_alive_vertex(2**32) and not box.is_alive_tet(2**32)
    assert not box.is_alive_vertex(-1) and box.is_alive_vertex(0)
    with pytest.raises(incise.InvalidArgument, match="the edge's two vertices are the same"):
        box.split_edge(0, 0, 0.5)


def test_write_refuses_what_read_would_refuse(box, tmp_path):
    path = str(tmp_path / "nan.vtu")
    with pytest.raises(incise.InvalidArgument, match="field 'x': cell #0 is nan"):
        incise.write(box, path, cell_data={"x": np.full(box.num_tets, np.nan)})
    pos = box.points.copy()
    pos[3, 1] = np.inf
    with pytest.raises(incise.InvalidArgument, match="non-finite point coordinate \\(point 3\\)"):
        incise.write(box, path, positions=pos)
    assert not (tmp_path / "nan.vtu").exists()


def test_copy_is_independent_and_refine_keeps_ids(box):
    c = box.copy()
    assert c.num_tets == box.num_tets and np.array_equal(c.tets, box.tets)
    c.split_tet(int(c.tet_ids[0]))
    assert c.num_tets == box.num_tets + 3  # the original is untouched
    r = incise.refine_uniform(box)
    assert r.num_tets == 8 * box.num_tets
    assert np.allclose(r.points[: box.num_vertices], box.points)  # the input's ids kept
    assert np.isclose(r.volume(), box.volume())
    r.validate()
    # A cut leaves dead slots: compact() first.
    cut = box.copy()
    k = incise.Cutter(cut)
    p, e = box.points.min(0), box.points.max(0)
    mid = 0.5 * (p + e)
    k.start((mid[0], p[1] - 1, e[2] + 1), (mid[0], e[1] + 1, e[2] + 1))
    k.advance((mid[0], p[1] - 1, mid[2]), (mid[0], e[1] + 1, mid[2]))
    k.finish()
    if cut.vertex_capacity > cut.num_vertices or cut.tet_capacity > cut.num_tets:
        with pytest.raises(incise.InvalidArgument, match="compact"):
            incise.refine_uniform(cut)
    dead_v, dead_t = cut.vertex_capacity - cut.num_vertices, cut.tet_capacity - cut.num_tets
    vmap, tmap = cut.compact()
    assert (vmap == -1).sum() == dead_v and (tmap == -1).sum() == dead_t  # dead ids map to -1
    assert np.array_equal(np.sort(tmap[tmap >= 0]), np.arange(cut.num_tets))
    rc = incise.refine_uniform(cut)
    rc.validate()
    assert rc.num_tets == 8 * cut.num_tets
    assert (rc.boundary_faces()[1] == incise.TAG_CUT).sum() == 4 * (cut.boundary_faces()[1] == incise.TAG_CUT).sum()


def test_compact_maps_dead_ids_to_minus_one(source_dir):
    # A cut through the sample liver leaves dead vertex slots (the improvement contracts edges);
    # compact() maps them to -1 (it once returned 2^32 - 1, an unsigned -1).
    mesh = incise.read(str(source_dir / "samples" / "liver.msh"))
    p = mesh.points
    lo, hi = p.min(0), p.max(0)
    ext, c = hi - lo, 0.5 * (p.min(0) + p.max(0))
    a0 = np.array([c[0], lo[1] + 0.25 * ext[1], hi[2] + 0.05 * ext[2]])
    b0 = np.array([c[0], lo[1] + 0.75 * ext[1], hi[2] + 0.05 * ext[2]])
    step = np.array([0.0, 0.0, -0.055 * ext[2]])
    cutter = incise.Cutter(mesh)
    cutter.start(a0, b0)
    for k in range(1, 11):
        cutter.advance(a0 + k * step, b0 + k * step)
    cutter.finish()
    dead = mesh.vertex_capacity - mesh.num_vertices
    assert dead > 0
    alive = mesh.vertex_ids
    vmap, _ = mesh.compact()
    assert (vmap == -1).sum() == dead
    assert np.array_equal(vmap[alive], np.arange(len(alive)))  # live vertices keep their order
