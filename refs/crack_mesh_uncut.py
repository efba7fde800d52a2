#!/usr/bin/python3
"""The crack mesh of the seed's beam (`mesh.py beam_crack`) with its crack's nodes shared, not
duplicated: the same nodes and tets as the pre-cut mesh of that size, the crack's faces and front
line mesh faces and edges but the body whole. X-FEM on it with the extended front equals FEM on the
pre-cut mesh, so the tip front can be set beside remeshed FEM on one mesh
(`examples/error_map.rs CASE tip|extend LEVEL mesh=DIR`). Kept apart from mesh.py, whose hash is
an input of every reference.

With --strip-edges HS the mesh is graded towards the free edges of the `*_face` cases' top-face
strips (x = 0.005 and x = 0.025 on z = 0.2; size HS there, growing as mesh.py grades), not towards
the crack front: the strip edge is a second singular line of those cases, and resolving it in the
mesh shows the crack treatments apart (refs/README.md, "Why the strip edges are graded").
With --uncut as well, the body is meshed without the crack (`mesh.py beam_uncut`'s geometry,
graded the same way): the study's setting, X-FEM's front inside elements, beside remeshed FEM
on the crack mesh graded alike.

    /usr/bin/python3 refs/crack_mesh_uncut.py 0.006 OUT/L2.msh   # h of the level: out/meshes/beam_crack/L2.json
    /usr/bin/python3 refs/crack_mesh_uncut.py 0.006 OUT/L2.msh --strip-edges 0.0015
    /usr/bin/python3 refs/crack_mesh_uncut.py 0.006 OUT/L2.msh --strip-edges 0.0015 --uncut
"""
from __future__ import annotations

import argparse
from pathlib import Path

import gmsh

import mesh
from mesh import check, generate, write_msh


def strip_graded(h: float, h_edge: float, front: bool = False, family: str = "beam_crack"):
    """`family`'s geometry (`beam_crack`, or `beam_uncut`: no crack) meshed with size h, graded to
    h_edge at the strips' free edges (and at the crack front too with `front`)."""
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.option.setNumber("Mesh.RandomSeed", 1)
        gmsh.model.add(f"{family}_strips")
        mesh.build_geometry(family)
        edges = []
        for dim, tag in gmsh.model.getEntities(1):
            x0, _, z0, x1, _, _ = gmsh.model.getBoundingBox(dim, tag)
            if any(abs(x0 - e) < 1e-5 and abs(x1 - e) < 1e-5 for e in mesh.STRIP_EDGES) and z0 > mesh.BOX[2] - 1e-5:
                edges.append(tag)
        if len(edges) != len(mesh.STRIP_EDGES):
            raise RuntimeError(f"found {len(edges)} strip edges, expected {len(mesh.STRIP_EDGES)}")
        if front:
            edges = mesh.singular_curves("beam_crack")
            if len(edges) != len(mesh.STRIP_EDGES) + 1:
                raise RuntimeError(f"found {len(edges)} singular curves, expected the strip edges and the front")
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.2 * h_edge)
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        field = gmsh.model.mesh.field
        dist = field.add("Distance")
        field.setNumbers(dist, "CurvesList", edges)
        field.setNumber(dist, "NumPointsPerCurve", int(mesh.BOX[1] / h_edge) * 4)
        thr = field.add("Threshold")
        field.setNumber(thr, "InField", dist)
        field.setNumber(thr, "SizeMin", h_edge)
        field.setNumber(thr, "SizeMax", h)
        field.setNumber(thr, "DistMin", 2 * h_edge)
        field.setNumber(thr, "DistMax", 2 * h_edge + (h - h_edge) / mesh.GRADING)
        field.setAsBackgroundMesh(thr)
        points, tets, _ = mesh.generate_tets()
    finally:
        gmsh.finalize()
    return mesh.used_nodes(points, tets)[:2]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("h", type=float, help="mesh size (m), as the level's h_far")
    ap.add_argument("out", type=Path)
    ap.add_argument("--strip-edges", type=float, metavar="HS",
                    help="grade towards the strips' free edges to size HS (m) instead of meshing uniformly")
    ap.add_argument("--front", action="store_true",
                    help="with --strip-edges: grade towards the crack front too, to the same size")
    ap.add_argument("--uncut", action="store_true",
                    help="with --strip-edges: mesh the body without the crack (beam_uncut's geometry)")
    a = ap.parse_args()
    if a.front and a.strip_edges is None:
        raise SystemExit("error: --front grades as --strip-edges HS does: give HS")
    if a.uncut and (a.strip_edges is None or a.front):
        raise SystemExit("error: --uncut grades at the strip edges only: give --strip-edges HS, not --front")
    family = "beam_uncut" if a.uncut else "beam_crack"
    if a.strip_edges is None:
        points, tets = generate(family, a.h)
    else:
        points, tets = strip_graded(a.h, a.strip_edges, a.front, family)
    check(family, points, tets, 0)
    write_msh(a.out, points, tets)
    print(f"{a.out}: {len(points)} nodes, {len(tets)} tets")


if __name__ == "__main__":
    main()
