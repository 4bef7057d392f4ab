"""Shared fixtures of the Python binding tests. CTest sets PYTHONPATH to build/python and
INCISE_SOURCE_DIR / INCISE_EXE / INCISE_CGAL_DATA_DIR; run by hand:
  PYTHONPATH=build/python INCISE_EXE=build/cli/incise /usr/bin/python3 -m pytest tests/python
"""
import os
import pathlib

import numpy as np
import pytest

import incise

SOURCE_DIR = pathlib.Path(os.environ.get("INCISE_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))


@pytest.fixture
def source_dir():
    return SOURCE_DIR


@pytest.fixture
def incise_exe():
    exe = os.environ.get("INCISE_EXE")
    if not exe:
        pytest.skip("INCISE_EXE not set")
    return exe


@pytest.fixture
def box():
    """1 x 0.2 x 0.2 bar of 10 x 2 x 2 cubes (240 Kuhn tets)."""
    return incise.generate_box((1.0, 0.2, 0.2), (10, 2, 2))


def signed_volumes(points, tets):
    a, b, c, d = (points[tets[:, k]] for k in range(4))
    return np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) / 6.0
