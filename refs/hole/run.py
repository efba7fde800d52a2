#!/usr/bin/python3
"""A slit towards a vessel against remeshed references (`make hole`): a 40 x 40 x 20 mm block
around a hole of radius 5 mm along z (a vessel), its bottom face y = 0 held, its top face y = 40 mm
moved by (1, 4, 0) mm, gravity along -z (E = 20 kPa, nu = 0.45, linear statics), and a slit in the
plane y = 20.3 mm from the face x = 0 to the front x = 10 mm, 5 mm short of the hole's wall.

Variants per level (gmsh meshes of size 4, 3, 2 mm): X-FEM on the block without the slit (its front
inside elements) with the front tip-enriched (`tip`), tip-enriched within 4 mm (`geo`) or extended
(`ext`), and FEM on the block meshed with the slit (its nodes duplicated, the front's shared), Tet4
and Tet10; each against our Tet10 solution on a mesh with the slit graded to 0.4 mm at the front
(the solver equals FEniCSx on the same mesh, tests/references.rs), whose own error is its
difference from one 1.4x coarser; and, to show what an ungraded reference would say, against
Tet10 on the uniform 1.3 mm slit mesh. Max probe error over the largest probe displacement.

Usage: /usr/bin/python3 run.py  (cached in refs/out/hole: delete a file to redo it). Writes
refs/out/hole/summary.txt."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import gmsh
import meshio
import numpy as np

REPO = Path(__file__).resolve().parents[2]
BIN = str(REPO / "target" / "release" / "xfem-cut")
ROOT = REPO / "refs" / "out" / "hole"
Y, XF = 0.0203, 0.010            # the slit's plane and front
LEVELS = [0.004, 0.003, 0.002]
REF = (0.002, 0.0004)            # graded reference: far size, size at the front
REFC = (0.0028, 0.00056)         # 1.4x coarser: the reference's own error
UNIFORM_REF = 0.0013             # the ungraded reference, for comparison
PROBES = [[0.0, 0.0204, 0.01], [0.0, 0.0202, 0.01], [0.005, 0.0204, 0.0], [0.005, 0.0202, 0.02],
          [0.04, 0.02, 0.01], [0.01, 0.03, 0.02], [0.012, 0.0203, 0.01], [0.03, 0.03, 0.0]]
CUT = f"[[cut]]\norigin = [-0.001, {Y}, -0.001]\nu = [0.0, 0.0, 0.022]\nv = [{XF + 0.001}, 0.0, 0.0]\n"
VARIANTS = {"tip": "", "geo": "tip_radius = 0.004\n", "ext": 'front = "extend"\n'}


def mesh(path: Path, h: float, slit: bool, h_front: float | None = None) -> None:
    """The block meshed at size h (graded to h_front within 1-8 mm of the front); with the slit,
    its nodes behind the front duplicated for the elements above it (cached)."""
    if not path.exists():
        write_block(path, h, XF if slit else None, duplicate=slit, h_front=h_front)


def write_block(path: Path, h: float, slit_to: float | None, duplicate: bool,
                h_front: float | None = None) -> None:
    """Writes the block meshed at size h, with the slit from x = 0 to x = `slit_to` as a face layer
    of the mesh (none: without it), graded to h_front within 1-8 mm of the slit's edge; with
    `duplicate`, the slit's nodes (those inside the body short of its edge) duplicated for the
    elements above it. MSH 4.1 ASCII as meshio writes it (tests/fixtures/hole_block.py too)."""
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    box = gmsh.model.occ.addBox(0, 0, 0, 0.04, 0.04, 0.02)
    hole = gmsh.model.occ.addCylinder(0.02, 0.02, -0.01, 0, 0, 0.04, 0.005)
    body, _ = gmsh.model.occ.cut([(3, box)], [(3, hole)])
    if slit_to is not None:
        r = gmsh.model.occ.addRectangle(0, 0, 0, slit_to, 0.02)
        gmsh.model.occ.rotate([(2, r)], 0, 0, 0, 1, 0, 0, np.pi / 2)
        gmsh.model.occ.translate([(2, r)], 0, Y, 0)
        gmsh.model.occ.fragment(body, [(2, r)])
    gmsh.model.occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMax", h)
    gmsh.option.setNumber("Mesh.MeshSizeMin", (h_front or h) / 3)
    if h_front is not None:
        front = [c for _, c in gmsh.model.getEntities(1)
                 if np.allclose(gmsh.model.occ.getCenterOfMass(1, c)[:2], [slit_to, Y], atol=1e-9)]
        f = gmsh.model.mesh.field.add("Distance")
        gmsh.model.mesh.field.setNumbers(f, "CurvesList", front)
        gmsh.model.mesh.field.setNumber(f, "NumPointsPerCurve", 200)
        t = gmsh.model.mesh.field.add("Threshold")
        gmsh.model.mesh.field.setNumber(t, "InField", f)
        for k, v in (("SizeMin", h_front), ("SizeMax", h), ("DistMin", 0.001), ("DistMax", 0.008)):
            gmsh.model.mesh.field.setNumber(t, k, v)
        gmsh.model.mesh.field.setAsBackgroundMesh(t)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
    gmsh.model.mesh.generate(3)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    points = coords.reshape(-1, 3)
    index = {int(t): i for i, t in enumerate(tags)}
    _, tet_nodes = gmsh.model.mesh.getElementsByType(4)
    tets = np.array([index[int(t)] for t in tet_nodes]).reshape(-1, 4)
    gmsh.finalize()
    used = np.unique(tets)
    remap = -np.ones(len(points), dtype=np.int64)
    remap[used] = np.arange(len(used))
    points, tets = points[used], remap[tets]
    if duplicate:
        # (the hole's wall at y = Y is at x = 15.0009 mm: a slit into it ends there)
        on_slit = (np.abs(points[:, 1] - Y) < 1e-9) & (points[:, 0] < min(slit_to - 1e-9, 0.0152))
        above = points[tets].mean(axis=1)[:, 1] > Y
        twin = -np.ones(len(points), dtype=np.int64)
        nodes = np.flatnonzero(on_slit)
        twin[nodes] = len(points) + np.arange(len(nodes))
        for e in np.flatnonzero(above):
            for k in range(4):
                if twin[tets[e, k]] >= 0:
                    tets[e, k] = twin[tets[e, k]]
        points = np.vstack([points, points[nodes]])
    path.parent.mkdir(parents=True, exist_ok=True)
    meshio.write(path, meshio.Mesh(points, [("tetra", tets)]), file_format="gmsh", binary=False)


def case(name: str, element: str, meshes: list[str], cut: str) -> Path:
    path = ROOT / f"{name}.toml"
    path.write_text(f"""name = "hole_{name}"
[body]
mesh = {meshes}
element = "{element}"
[material]
young = 2.0e4
poisson = 0.45
density = 1050.0
{cut}
[[fix]]
min = [-inf, -inf, -inf]
max = [inf, 0.0, inf]
[[fix]]
min = [-inf, 0.04, -inf]
max = [inf, inf, inf]
displacement = [0.001, 0.004, 0.0]
[gravity]
acceleration = [0.0, 0.0, -9.81]
[analysis]
type = "static"
[[probe]]
points = {PROBES}
""".replace("'", '"'))
    return path


def run(name: str, level: int) -> tuple[int, np.ndarray]:
    """DOFs and probe displacements of case `name` at `level` (cached)."""
    out = ROOT / "out" / f"{name}_L{level}"
    log = out.with_suffix(".log")
    if not (out / "probes.csv").exists():
        p = subprocess.run([BIN, "run", str(ROOT / f"{name}.toml"), "--level", str(level), "--out", str(out)],
                           capture_output=True, text=True)
        if p.returncode != 0:
            sys.exit(f"{name} L{level}: {p.stderr.strip()}")
        log.write_text(p.stdout)
    dofs = int(re.search(r"(\d+) DOFs", log.read_text()).group(1))
    return dofs, np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)[:, 3:6]


def error(u: np.ndarray, ref: np.ndarray) -> float:
    return float(np.linalg.norm(u - ref, axis=1).max() / np.linalg.norm(ref, axis=1).max())


def main() -> None:
    ROOT.mkdir(parents=True, exist_ok=True)
    for h in LEVELS:
        mesh(ROOT / f"u{h * 1e3:g}.msh", h, slit=False)
        mesh(ROOT / f"p{h * 1e3:g}.msh", h, slit=True)
    mesh(ROOT / "ref.msh", *REF[:1], slit=True, h_front=REF[1])
    mesh(ROOT / "refc.msh", *REFC[:1], slit=True, h_front=REFC[1])
    mesh(ROOT / "uniform_ref.msh", UNIFORM_REF, slit=True)
    uncut = [f"u{h * 1e3:g}.msh" for h in LEVELS]
    precut = [f"p{h * 1e3:g}.msh" for h in LEVELS]
    for name, meshes in (("ref", ["ref.msh"]), ("refc", ["refc.msh"]), ("uniform_ref", ["uniform_ref.msh"])):
        case(name, "tet10", meshes, "")
    rows = []
    for element in ("tet4", "tet10"):
        rows.append((f"fem_{element}", case(f"fem_{element}", element, precut, "")))
        for var, extra in VARIANTS.items():
            rows.append((f"{var}_{element}", case(f"{var}_{element}", element, uncut, CUT + extra)))
    ref_dofs, ref = run("ref", 0)
    _, refc = run("refc", 0)
    _, uniform = run("uniform_ref", 0)
    lines = [f"reference: Tet10 on the slit mesh graded to {REF[1] * 1e3:g} mm at the front, {ref_dofs} DOFs; "
             f"its own error (against one 1.4x coarser) {error(refc, ref):.2e}; the uniform {UNIFORM_REF * 1e3:g} mm "
             f"slit mesh's Tet10 differs from it by {error(uniform, ref):.2e}",
             "max probe error over the largest probe displacement, against the graded reference "
             "[against the uniform one]; levels of size " + ", ".join(f"{h * 1e3:g}" for h in LEVELS) + " mm"]
    for name, _ in rows:
        cells, errs = [], []
        for level in range(len(LEVELS)):
            dofs, u = run(name, level)
            errs.append(error(u, ref))
            cells.append(f"L{level} {dofs:6d} DOFs {errs[-1] * 100:6.3f} % [{error(u, uniform) * 100:6.3f} %]")
        falls = all(b < a for a, b in zip(errs, errs[1:]))
        lines.append(f"{name:10s} " + " | ".join(cells) + f" | falls at every level: {'yes' if falls else 'NO'}")
    text = "\n".join(lines) + "\n"
    (ROOT / "summary.txt").write_text(text)
    print(text, end="")


if __name__ == "__main__":
    main()
