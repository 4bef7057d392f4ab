"""meshio cross-checks for the incise io tests (run with /usr/bin/python3, Debian's meshio).

  meshio_tool.py check NPOINTS NTETS LABELS_FILE COORD_SUM FILE...
      meshio reads each FILE; it must hold NPOINTS points, NTETS tetra cells whose labels (the
      first of label / gmsh:physical / medit:ref / tetgen:ref) equal the integers in
      LABELS_FILE, and points whose coordinates sum to COORD_SUM (relative 1e-12).
  meshio_tool.py rewrite SRC OUTDIR
      meshio reads SRC (a labeled tet mesh) and writes it in every tet format it writes; prints
      one line per file: NAME CARRIES_LABELS.
Exit code 0 on success, 1 with a message otherwise.
"""
import os
import sys

import numpy as np
import meshio

LABEL_KEYS = ("label", "gmsh:physical", "medit:ref", "tetgen:ref")


def tet_labels(mesh):
    for key in LABEL_KEYS:
        if key in mesh.cell_data:
            parts = [d for c, d in zip(mesh.cells, mesh.cell_data[key]) if c.type == "tetra"]
            if parts:
                return key, np.concatenate(parts).astype(np.int64).ravel()
    return None, None


def check(path, npoints, ntets, labels_file, coord_sum):
    m = meshio.read(path)
    errors = []
    if len(m.points) != npoints:
        errors.append(f"{len(m.points)} points, expected {npoints}")
    nt = sum(len(c.data) for c in m.cells if c.type == "tetra")
    if nt != ntets:
        errors.append(f"{nt} tetra, expected {ntets}")
    expected = np.loadtxt(labels_file, dtype=np.int64, ndmin=1)
    key, labels = tet_labels(m)
    if labels is None:
        errors.append(f"no label array among {list(m.cell_data.keys())}")
    elif len(labels) != len(expected) or not np.array_equal(labels, expected):
        errors.append(f"labels ({key}) differ")
    s = float(np.sum(m.points[:, :3]))
    if abs(s - coord_sum) > 1e-12 * max(1.0, abs(coord_sum)) * 10:
        errors.append(f"coordinate sum {s!r}, expected {coord_sum!r}")
    if errors:
        print(f"{path}: " + "; ".join(errors))
        return 1
    return 0


def rewrite(src, outdir):
    m = meshio.read(src)
    tets = np.concatenate([c.data for c in m.cells if c.type == "tetra"])
    labels = np.concatenate(
        [d for c, d in zip(m.cells, m.cell_data["label"]) if c.type == "tetra"]).astype(np.int32)
    pts = m.points
    cells = [("tetra", tets)]

    def mesh_with(key):
        return meshio.Mesh(pts, cells, cell_data={key: [labels]})

    out = []
    msh = meshio.Mesh(pts, cells, cell_data={"gmsh:physical": [labels], "gmsh:geometrical": [labels]})
    meshio.write(os.path.join(outdir, "m22.msh"), msh, file_format="gmsh22", binary=False)
    out.append(("m22.msh", 1))
    meshio.write(os.path.join(outdir, "m41.msh"), meshio.Mesh(pts, cells), file_format="gmsh", binary=False)
    out.append(("m41.msh", 0))  # meshio's 4.1 writer drops physical tags without entity data
    meshio.write(os.path.join(outdir, "ascii.vtu"), mesh_with("label"), binary=False)
    out.append(("ascii.vtu", 1))
    meshio.write(os.path.join(outdir, "raw.vtu"), mesh_with("label"), binary=True, compression=None)
    out.append(("raw.vtu", 1))
    meshio.write(os.path.join(outdir, "zlib.vtu"), mesh_with("label"), binary=True)
    out.append(("zlib.vtu", 1))
    meshio.write(os.path.join(outdir, "u64.vtu"), mesh_with("label"), binary=True, compression=None,
                 header_type="UInt64")
    out.append(("u64.vtu", 1))
    meshio.write(os.path.join(outdir, "ascii.vtk"), mesh_with("label"), binary=False)
    out.append(("ascii.vtk", 1))
    meshio.write(os.path.join(outdir, "binary.vtk"), mesh_with("label"), binary=True)
    out.append(("binary.vtk", 1))
    meshio.write(os.path.join(outdir, "medit.mesh"), mesh_with("medit:ref"))
    out.append(("medit.mesh", 1))
    meshio.write(os.path.join(outdir, "tg.node"), mesh_with("tetgen:ref"))
    out.append(("tg.node", 1))
    for name, carries in out:
        print(name, carries)
    return 0


def main(argv):
    import warnings
    warnings.simplefilter("ignore")
    if len(argv) >= 7 and argv[1] == "check":
        rc = 0
        for path in argv[6:]:
            try:
                rc |= check(path, int(argv[2]), int(argv[3]), argv[4], float(argv[5]))
            except Exception as e:  # a file meshio cannot read at all
                print(f"{path}: meshio failed: {e}")
                rc = 1
        return rc
    if len(argv) == 4 and argv[1] == "rewrite":
        return rewrite(argv[2], argv[3])
    print(__doc__)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv))
