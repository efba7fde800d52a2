"""Shared helpers of the reference pipeline: case files, VTU output, hashing."""
from __future__ import annotations

import hashlib
import json
import os
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
OUT = ROOT / "out"
CASES = ROOT.parent / "cases"

# VTK cell types.
VTK_TETRA, VTK_QUADRATIC_TETRA = 10, 24
# Our (and VTK's) Tet10 edge order: mid-node 4 + k sits on edge EDGES[k].
EDGES = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]


def load_case(name: str) -> dict:
    with open(CASES / f"{name}.toml", "rb") as f:
        return tomllib.load(f)


def lame(case: dict) -> tuple[float, float, float]:
    m = case["material"]
    e, nu = m["young"], m["poisson"]
    return e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu)), m["density"]


def write_vtu(path: Path, points: np.ndarray, cells: np.ndarray, cell_type: int, u: np.ndarray) -> None:
    """ASCII VTU with full double precision (meshio's ASCII writer keeps only 12 digits), written atomically."""
    path.parent.mkdir(parents=True, exist_ok=True)
    n, m = len(points), len(cells)
    fmt = lambda a: "\n".join(" ".join(repr(float(x)) for x in row) for row in a)
    text = [
        '<?xml version="1.0"?>',
        '<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">',
        "<UnstructuredGrid>",
        f'<Piece NumberOfPoints="{n}" NumberOfCells="{m}">',
        '<Points>\n<DataArray type="Float64" Name="Points" NumberOfComponents="3" format="ascii">',
        fmt(points),
        "</DataArray>\n</Points>\n<Cells>",
        '<DataArray type="Int64" Name="connectivity" format="ascii">',
        "\n".join(" ".join(str(int(i)) for i in c) for c in cells),
        '</DataArray>\n<DataArray type="Int64" Name="offsets" format="ascii">',
        " ".join(str(cells.shape[1] * (i + 1)) for i in range(m)),
        '</DataArray>\n<DataArray type="UInt8" Name="types" format="ascii">',
        " ".join([str(cell_type)] * m),
        "</DataArray>\n</Cells>\n<PointData>",
        '<DataArray type="Float64" Name="u" NumberOfComponents="3" format="ascii">',
        fmt(u),
        "</DataArray>\n</PointData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n",
    ]
    tmp = path.with_suffix(".tmp")
    tmp.write_text("\n".join(text))
    os.replace(tmp, path)


def file_hash(*paths: Path, extra: str = "") -> str:
    h = hashlib.sha256(extra.encode())
    for p in paths:
        h.update(p.read_bytes())
    return h.hexdigest()[:16]


def write_json(path: Path, data: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True))
    os.replace(tmp, path)
