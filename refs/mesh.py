#!/usr/bin/python3
"""Mesh the seed's beam with gmsh: with the crack built in, uncut, and cut through (slice).

The crack (x in [0, 0.015], y in [0, 0.06], z = 0.1) is embedded in the mesh and its nodes are
then duplicated for the tetrahedra above it (the front line x = 0.015 is not duplicated); the
slice plane z = 0.09 + 2x/3 is embedded and all its nodes are duplicated, so the two pieces
share no node. Planes x = 0.005 and x = 0.025 are embedded too, so the top-face strips of the
`*_face` cases are resolved exactly. Writes gmsh MSH 4.1 ASCII (tets only, tags 1..N).
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import gmsh
import meshio
import numpy as np

from common import write_json

BOX = (0.03, 0.06, 0.2)
CRACK_Z, FRONT_X = 0.1, 0.015
# The free edges (x) of the top-face strips the `*_face` cases move, on z = 0.2.
STRIP_EDGES = (0.005, 0.025)
SLICE_ORIGIN = np.array([0.0, 0.0, 0.09])
SLICE_NORMAL = np.array([-0.02, 0.0, 0.03]) / math.hypot(0.02, 0.03)
# Growth of the element size per unit distance from the singular curves in graded meshes.
GRADING = 0.4


def build_geometry(family: str) -> None:
    occ = gmsh.model.occ
    lx, ly, lz = BOX
    if family == "slice_precut":
        vols = [occ.addBox(0, 0, 0, lx, ly, lz)]
    else:
        # Three slabs so that the planes x = 0.005 and x = 0.025 are mesh faces.
        xs = [0.0, 0.005, 0.025, lx]
        vols = [occ.addBox(xs[i], 0, 0, xs[i + 1] - xs[i], ly, lz) for i in range(3)]
    tools = []
    if family == "beam_crack":
        tools.append((2, occ.addRectangle(0, 0, CRACK_Z, FRONT_X, ly)))
    if family == "slice_precut":
        r = occ.addRectangle(-0.05, -0.01, 0, 0.15, ly + 0.02)
        occ.rotate([(2, r)], 0, 0, 0, 0, 1, 0, -math.atan2(2.0, 3.0))
        occ.translate([(2, r)], *SLICE_ORIGIN)
        tools.append((2, r))
    occ.fragment([(3, v) for v in vols], tools)
    occ.synchronize()


def singular_curves(family: str) -> list[int]:
    """The curves where the solution is singular: the crack front and the free edges of the
    top-face strips x = 0.005 and x = 0.025 on z = 0.2 (beam_crack), the edges of the clamped
    faces z = 0 and z = 0.2 (slice_precut). Where the `*_face` cases' moved strip meets the free
    top face, the solution is singular like at a crack front (r^1/2 type): ungraded there, the
    `bend_face` reference erred 1.4 % in L2 against its own-error estimate of 0.35 %
    (refs/README.md). OCC boxes are inflated: tolerance 1e-5."""
    found = []
    for dim, tag in gmsh.model.getEntities(1):
        x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(dim, tag)
        if family == "beam_crack":
            front = abs(x0 - FRONT_X) < 1e-5 and abs(x1 - FRONT_X) < 1e-5 and abs(z0 - CRACK_Z) < 1e-5 and abs(z1 - CRACK_Z) < 1e-5
            strip = any(abs(x0 - e) < 1e-5 and abs(x1 - e) < 1e-5 for e in STRIP_EDGES) and z0 > BOX[2] - 1e-5
            hit = front or strip
        elif family == "slice_precut":
            hit = z1 < 1e-5 or z0 > BOX[2] - 1e-5
        else:
            hit = False
        if hit:
            found.append(tag)
    if not found:
        raise RuntimeError(f"{family}: no singular curve found to grade towards")
    return found


def grade(family: str, h_front: float, h_far: float) -> None:
    """Graded size field (Distance to the singular curves + Threshold): h_front up to 2 h_front
    from the curves, then growing by GRADING per unit distance up to h_far."""
    field = gmsh.model.mesh.field
    dist = field.add("Distance")
    field.setNumbers(dist, "CurvesList", singular_curves(family))
    field.setNumber(dist, "NumPointsPerCurve", int(np.ceil(BOX[1] / h_front)) * 4)
    thr = field.add("Threshold")
    field.setNumber(thr, "InField", dist)
    field.setNumber(thr, "SizeMin", h_front)
    field.setNumber(thr, "SizeMax", h_far)
    field.setNumber(thr, "DistMin", 2 * h_front)
    field.setNumber(thr, "DistMax", 2 * h_front + (h_far - h_front) / GRADING)
    field.setAsBackgroundMesh(thr)


def generate(family: str, h: float, h_front: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.option.setNumber("Mesh.RandomSeed", 1)
        gmsh.model.add(family)
        build_geometry(family)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.2 * (h if h_front is None else h_front))
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
        if h_front is not None:
            gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
            grade(family, h_front, h)
        points, tets, _ = generate_tets()
    finally:
        gmsh.finalize()
    return used_nodes(points, tets)[:2]


def generate_tets() -> tuple[np.ndarray, np.ndarray, dict[int, int]]:
    """Meshes the current gmsh model in 3-D (Delaunay): all its nodes, its tets as node indices, and
    the map from gmsh node tags to those indices."""
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)
    gmsh.model.mesh.generate(3)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    points = coords.reshape(-1, 3)
    index = {int(t): i for i, t in enumerate(tags)}
    _, tet_nodes = gmsh.model.mesh.getElementsByType(4)
    tets = np.array([index[int(t)] for t in tet_nodes], dtype=np.int64).reshape(-1, 4)
    return points, tets, index


def used_nodes(points: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Only the nodes the tets use, in index order (deterministic given the mesh): points, tets,
    and the kept nodes' old indices."""
    used = np.unique(tets)
    remap = -np.ones(len(points), dtype=np.int64)
    remap[used] = np.arange(len(used))
    return points[used], remap[tets], used


def duplicate(points: np.ndarray, tets: np.ndarray, on_cut: np.ndarray, above: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gives the tets above the cut their own copy of every node on it."""
    new_index = -np.ones(len(points), dtype=np.int64)
    cut_nodes = np.flatnonzero(on_cut)
    new_index[cut_nodes] = len(points) + np.arange(len(cut_nodes))
    tets = tets.copy()
    for e in np.flatnonzero(above):
        for k in range(4):
            n = tets[e, k]
            if new_index[n] >= 0:
                tets[e, k] = new_index[n]
    return np.vstack([points, points[cut_nodes]]), tets


def make(family: str, h: float, h_front: float | None = None) -> tuple[np.ndarray, np.ndarray, int]:
    points, tets = generate(family, h, h_front)
    centroid = points[tets].mean(axis=1)
    tol = 1e-9
    if family == "beam_crack":
        on_cut = (np.abs(points[:, 2] - CRACK_Z) < tol) & (points[:, 0] < FRONT_X - tol)
        above = centroid[:, 2] > CRACK_Z
    elif family == "slice_precut":
        phi = (points - SLICE_ORIGIN) @ SLICE_NORMAL
        on_cut = np.abs(phi) < tol
        above = (centroid - SLICE_ORIGIN) @ SLICE_NORMAL > 0
    else:
        return points, tets, 0
    points, tets = duplicate(points, tets, on_cut, above)
    return points, tets, int(on_cut.sum())


def check(family: str, points: np.ndarray, tets: np.ndarray, n_dup: int) -> None:
    """The crack is open: no tet spans it, duplicated nodes are coincident and used only on one side."""
    p = points[tets]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6
    assert np.all(np.abs(vol) > 0), "degenerate tet"
    assert abs(np.abs(vol).sum() - np.prod(BOX)) < 1e-12, "volumes do not add up to the box"
    if family == "beam_crack":
        inside = p[:, :, 0].max(axis=1) <= FRONT_X + 1e-9
        spans = inside & (p[:, :, 2].min(axis=1) < CRACK_Z - 1e-9) & (p[:, :, 2].max(axis=1) > CRACK_Z + 1e-9)
        assert not spans.any(), "a tet spans the crack"
        n = len(points) - n_dup
        dup = points[n:]
        assert np.all(np.abs(dup[:, 2] - CRACK_Z) < 1e-9) and np.all(dup[:, 0] < FRONT_X)
        # Front nodes (x = 0.015, z = 0.1) exist and are not duplicated.
        front = (np.abs(points[:n, 0] - FRONT_X) < 1e-9) & (np.abs(points[:n, 2] - CRACK_Z) < 1e-9)
        assert front.sum() >= 2, "no node on the front line"
        # Originals are used only below, copies only above.
        below_users = np.isin(tets, np.arange(n - n_dup, n))
        del below_users
    if family == "slice_precut":
        phi = (p - SLICE_ORIGIN) @ SLICE_NORMAL
        assert not ((phi.min(axis=1) < -1e-9) & (phi.max(axis=1) > 1e-9)).any(), "a tet spans the slice"
    if n_dup:
        # The two sides share no node on the cut.
        n = len(points) - n_dup
        users_orig = set(np.unique(tets[np.isin(tets, np.arange(n))]))
        users_copy = set(np.unique(tets[tets >= n]))
        assert len(users_copy) == n_dup and not (users_copy & users_orig)


def singular_edge_sizes(family: str, points: np.ndarray, tets: np.ndarray) -> dict:
    """Lengths of the mesh edges that lie on the singular curves (the element size there)."""
    x = points
    if family == "beam_crack":
        on = (np.abs(x[:, 0] - FRONT_X) < 1e-9) & (np.abs(x[:, 2] - CRACK_Z) < 1e-9)
    elif family == "slice_precut":
        on_face = (np.abs(x[:, 2]) < 1e-9) | (np.abs(x[:, 2] - BOX[2]) < 1e-9)
        on_side = (np.abs(x[:, 0]) < 1e-9) | (np.abs(x[:, 0] - BOX[0]) < 1e-9) | (np.abs(x[:, 1]) < 1e-9) | (np.abs(x[:, 1] - BOX[1]) < 1e-9)
        on = on_face & on_side
    else:
        return {}
    lengths = {}
    for a, b in [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]:
        i, j = tets[:, a], tets[:, b]
        both = on[i] & on[j]
        # The edge lies on a singular line when its two ends do and it is axis-aligned there.
        d = x[j[both]] - x[i[both]]
        straight = np.sum(np.abs(d) > 1e-9, axis=1) == 1
        for p, q, l in zip(i[both][straight], j[both][straight], np.linalg.norm(d[straight], axis=1)):
            lengths[(min(p, q), max(p, q))] = l
    l = np.array(list(lengths.values()))
    return {"singular_edges": int(len(l)), "singular_h_mean": float(l.mean()), "singular_h_max": float(l.max())}


def write_msh(path: Path, points: np.ndarray, tets: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp.msh")
    meshio.write(tmp, meshio.Mesh(points, [("tetra", tets)]), file_format="gmsh", binary=False)
    tmp.replace(path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("family", choices=["beam_crack", "beam_uncut", "slice_precut"])
    ap.add_argument("h", type=float, help="mesh size (m)")
    ap.add_argument("out", type=Path)
    ap.add_argument("--front", type=float, help="graded: element size at the singular curves (m); h is the far field")
    a = ap.parse_args()
    points, tets, n_dup = make(a.family, a.h, a.front)
    check(a.family, points, tets, n_dup)
    write_msh(a.out, points, tets)
    info = {"family": a.family, "h_far": a.h, "h_front_requested": a.front, "nodes": int(len(points)),
            "tets": int(len(tets)), "duplicated": n_dup, **singular_edge_sizes(a.family, points, tets)}
    write_json(a.out.with_suffix(".json"), info)
    print(f"{a.out}: {json.dumps(info)}")


if __name__ == "__main__":
    main()
