#!/usr/bin/python3
"""Keeps the largest face-connected part of a tet mesh (an organ meshed from an image carries
specks, which a static scene refuses as free parts). usage: largest_part.py IN.msh OUT.msh"""
import sys

import meshio
import numpy as np


def main():
    src, dst = sys.argv[1:3]
    m = meshio.read(src)
    tets = next(c.data for c in m.cells if c.type == "tetra")
    parent = np.arange(len(tets))

    def find(a):
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    first = {}
    for t, tet in enumerate(tets):
        for f in ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)):
            key = tuple(sorted(tet[list(f)]))
            if key in first:
                parent[find(t)] = find(first[key])
            else:
                first[key] = t
    roots = np.array([find(t) for t in range(len(tets))])
    ids, counts = np.unique(roots, return_counts=True)
    keep = roots == ids[np.argmax(counts)]
    gone = np.setdiff1d(tets[~keep].ravel(), tets[keep].ravel())
    cells, data = [], {k: [] for k in m.cell_data}
    for i, block in enumerate(m.cells):
        k = keep if block.type == "tetra" else ~np.isin(block.data, gone).any(axis=1)
        cells.append((block.type, block.data[k]))
        for name in m.cell_data:
            data[name].append(m.cell_data[name][i][k])
    meshio.write(dst, meshio.Mesh(m.points, cells, cell_data=data), file_format="gmsh22", binary=False)
    print(f"largest_part: kept {int(keep.sum())} of {len(tets)} tets ({len(ids)} parts)")


if __name__ == "__main__":
    main()
