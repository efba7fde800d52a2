#!/usr/bin/python3
"""Random oblique crack scenes in the seed beam's box: scene sampling, pre-cut gmsh meshes (the
patch embedded by OCC fragment, its nodes duplicated for the tets on its + side, the front's
nodes not), their checks, and the case files for X-FEM (structured box levels) and pre-cut FEM."""
from __future__ import annotations

import math
from pathlib import Path

import sys

import gmsh
import meshio
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from mesh import generate_tets, used_nodes  # noqa: E402

BOX = np.array([0.03, 0.06, 0.2])
MARGIN = 0.003


# ---------------------------------------------------------------- geometry helpers
def clip_polygon(poly: list[np.ndarray]) -> list[np.ndarray]:
    """Sutherland-Hodgman clip of a planar polygon by the box's 6 half-spaces."""
    for axis in range(3):
        for side in (0, 1):
            out = []
            lim = 0.0 if side == 0 else BOX[axis]

            def inside(p):
                return p[axis] >= lim if side == 0 else p[axis] <= lim
            n = len(poly)
            for i in range(n):
                a, b = poly[i], poly[(i + 1) % n]
                ia, ib = inside(a), inside(b)
                if ia:
                    out.append(a)
                if ia != ib:
                    t = (lim - a[axis]) / (b[axis] - a[axis])
                    out.append(a + t * (b - a))
            poly = out
            if not poly:
                return []
    return poly


def on_box_boundary(p: np.ndarray, tol: float = 1e-7) -> bool:
    return bool(np.any(np.abs(p) < tol) or np.any(np.abs(p - BOX) < tol))


def dist_to_box_edges(p: np.ndarray) -> float:
    """Distance from p (on/in the box) to the nearest of the box's 12 edges."""
    d = []
    for axis in range(3):
        o = [a for a in range(3) if a != axis]
        for c0 in (0.0, BOX[o[0]]):
            for c1 in (0.0, BOX[o[1]]):
                d.append(math.hypot(p[o[0]] - c0, p[o[1]] - c1))
    return min(d)


def front_segments(origin, u, v):
    """Parts of the patch's 4 edges inside the box: list of (a, b, outward in-plane normal)."""
    corners = [origin, origin + u, origin + u + v, origin + v]
    centre = origin + 0.5 * (u + v)
    n = np.cross(u, v)
    n /= np.linalg.norm(n)
    segs = []
    for i in range(4):
        a, b = corners[i], corners[(i + 1) % 4]
        # clip segment to box
        t0, t1 = 0.0, 1.0
        d = b - a
        ok = True
        for axis in range(3):
            for lim, sgn in ((0.0, 1), (BOX[axis], -1)):
                # inside: sgn*(a+t d - lim) >= 0
                num = sgn * (a[axis] - lim)
                den = sgn * d[axis]
                if abs(den) < 1e-15:
                    if num < 0:
                        ok = False
                else:
                    t = -num / den
                    if den > 0:
                        t0 = max(t0, t)
                    else:
                        t1 = min(t1, t)
        if ok and t1 - t0 > 1e-9:
            pa, pb = a + t0 * d, a + t1 * d
            mid = 0.5 * (pa + pb)
            out = np.cross(d, n)
            out /= np.linalg.norm(out)
            if out @ (mid - centre) < 0:
                out = -out
            segs.append((pa, pb, out))
    return segs


# ---------------------------------------------------------------- scene sampling
def sample_scene(seed: int, kind: str) -> dict:
    rng = np.random.default_rng(seed)
    for _ in range(100000):
        # oblique normal: every component at least 0.25 in magnitude
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        if np.min(np.abs(n)) < 0.25:
            continue
        t = np.cross(n, [0.0, 0.0, 1.0] if abs(n[2]) < 0.9 else [1.0, 0.0, 0.0])
        t /= np.linalg.norm(t)
        w = np.cross(n, t)
        ang = rng.uniform(0, 2 * math.pi)
        e1 = math.cos(ang) * t + math.sin(ang) * w
        e2 = np.cross(n, e1)
        skew = rng.uniform(-0.35, 0.35) if rng.random() < 0.5 else 0.0
        if kind == "inside":
            a, b = rng.uniform(0.010, 0.022), rng.uniform(0.010, 0.030)
        else:
            a, b = rng.uniform(0.015, 0.045), rng.uniform(0.015, 0.06)
        u = a * e1
        v = b * (math.cos(skew) * e2 + math.sin(skew) * e1)
        c = np.array([rng.uniform(0, BOX[0]), rng.uniform(0, BOX[1]), rng.uniform(0.075, 0.125)])
        origin = c - 0.5 * (u + v)
        corners = [origin, origin + u, origin + u + v, origin + v]
        inside = [bool(np.all(p > MARGIN) and np.all(p < BOX - MARGIN)) for p in corners]
        outside = [bool(np.any(p < -MARGIN) or np.any(p > BOX + MARGIN)) for p in corners]
        if not all(i or o for i, o in zip(inside, outside)):
            continue  # a corner too close to the boundary
        n_in = sum(inside)
        if kind == "inside" and n_in != 4:
            continue
        if kind == "edge" and n_in != 2:
            continue
        if kind == "corner" and n_in != 1:
            continue
        if kind == "edge":
            # the two inside corners must be adjacent (one edge outside, crack enters through the body's surface)
            idx = [i for i in range(4) if inside[i]]
            if (idx[1] - idx[0]) not in (1, 3):
                continue
        poly = clip_polygon(corners)
        if len(poly) < 3:
            continue
        if any(on_box_boundary(p) and dist_to_box_edges(p) < MARGIN for p in poly):
            continue
        if any(p[2] < 0.06 or p[2] > 0.14 for p in poly):
            continue  # keep the cut in the middle third (with a little slack for oblique patches)
        segs = front_segments(origin, u, v)
        segs = [s for s in segs if not (on_box_boundary(s[0]) and on_box_boundary(s[1]) and on_box_boundary(0.5 * (s[0] + s[1])))]
        front_len = sum(np.linalg.norm(s[1] - s[0]) for s in segs)
        if front_len < 0.010:
            continue
        # cut faces: crossing angle with the entry faces not too shallow
        bad = False
        for p in poly:
            for axis in range(3):
                if (abs(p[axis]) < 1e-9 or abs(p[axis] - BOX[axis]) < 1e-9) and abs(n[axis]) > 0.92:
                    bad = True
        if bad:
            continue
        # the section area left: the cut area must be < 70 % of the plane's section through the box
        area = polygon_area(poly, n)
        big = clip_polygon([c + 1.0 * (-e1 - e2), c + 1.0 * (e1 - e2), c + 1.0 * (e1 + e2), c + 1.0 * (-e1 + e2)])
        if area > 0.7 * polygon_area(big, n):
            continue
        break
    else:
        raise RuntimeError("no scene")
    young = float(10 ** rng.uniform(4, 6))
    nu = float(rng.uniform(0.2, 0.45))
    load = "gravity" if rng.random() < 0.6 else "top"
    g = rng.normal(size=3)
    g = 10.0 * g / np.linalg.norm(g)
    d = rng.normal(size=3)
    d = rng.uniform(0.002, 0.005) * d / np.linalg.norm(d)
    return {"seed": seed, "kind": kind, "origin": origin, "u": u, "v": v, "n": n, "young": young, "nu": nu,
            "load": load, "gravity": g, "top": d, "poly": poly, "front": segs, "area": area}


def polygon_area(poly, n):
    s = np.zeros(3)
    for i in range(len(poly)):
        s += np.cross(poly[i], poly[(i + 1) % len(poly)])
    return abs(s @ n) / 2


def probes(sc: dict) -> np.ndarray:
    n = sc["n"]
    poly = sc["poly"]
    pc = np.mean(poly, axis=0)
    zt = 0.2 if sc["load"] == "gravity" else 0.19  # top-face probes are prescribed under a top displacement
    pts = [[0.0, 0.0, zt], [0.03, 0.06, zt], [0.015, 0.06, zt], [0.03, 0.0, zt]]
    pts += [pc + 0.002 * n, pc - 0.002 * n]
    # a second pair, between the centre and the first polygon vertex
    q = 0.5 * (pc + poly[0])
    pts += [q + 0.0015 * n, q - 0.0015 * n]
    # near the front: 2.5 mm ahead of the middle of the longest front segment, and 2 mm above/below its middle
    a, b, out = max(sc["front"], key=lambda s: np.linalg.norm(s[1] - s[0]))
    m = 0.5 * (a + b)
    pts += [m + 0.0025 * out, m + 0.002 * n - 0.001 * out, m - 0.002 * n - 0.001 * out]
    pts += [[0.015, 0.03, 0.03], [0.005, 0.05, 0.17]]
    pts = np.array(pts, dtype=float)
    return np.clip(pts, 0.0, BOX)


# ---------------------------------------------------------------- pre-cut meshes
def graded_towards(kind: str, entities: list[int], points: int, h_min: float, h_max: float, d_min: float) -> int:
    """A gmsh size field: h_min within d_min of the curves or surfaces `entities` (`kind` =
    "CurvesList" or "SurfacesList"), growing by 0.4 per unit distance up to h_max."""
    f = gmsh.model.mesh.field
    dist = f.add("Distance")
    f.setNumbers(dist, kind, entities)
    f.setNumber(dist, "NumPointsPerCurve", points)
    thr = f.add("Threshold")
    f.setNumber(thr, "InField", dist)
    f.setNumber(thr, "SizeMin", h_min)
    f.setNumber(thr, "SizeMax", h_max)
    f.setNumber(thr, "DistMin", d_min)
    f.setNumber(thr, "DistMax", d_min + (h_max - h_min) / 0.4)
    return thr


def mesh_precut(sc: dict, h_far: float, h_front: float | None, path: Path, h_surf: float | None = None) -> dict:
    origin, u, v = sc["origin"], sc["u"], sc["v"]
    n = np.cross(u, v)
    n /= np.linalg.norm(n)
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.option.setNumber("Mesh.RandomSeed", 1)
        gmsh.model.add("precut")
        occ = gmsh.model.occ
        box = occ.addBox(0, 0, 0, *BOX)
        corners = [origin, origin + u, origin + u + v, origin + v]
        pts = [occ.addPoint(*p) for p in corners]
        lines = [occ.addLine(pts[i], pts[(i + 1) % 4]) for i in range(4)]
        loop = occ.addCurveLoop(lines)
        surf = occ.addPlaneSurface([loop])
        inter, _ = occ.intersect([(2, surf)], [(3, box)], removeObject=True, removeTool=False)
        out, outmap = occ.fragment([(3, box)], inter)
        occ.synchronize()
        vols = [t for d, t in out if d == 3]
        assert len(vols) == 1, f"fragment gave {len(vols)} volumes"
        cut_surfs = sorted({t for m in outmap[1:] for d, t in m if d == 2})
        bnd = gmsh.model.getBoundary([(2, s) for s in cut_surfs], combined=True, oriented=False)
        front_curves = []
        for d, c in bnd:
            lo, hi = gmsh.model.getParametrizationBounds(1, c)
            mid = np.array(gmsh.model.getValue(1, c, [0.5 * (lo[0] + hi[0])]))
            if not on_box_boundary(mid, 1e-6):
                front_curves.append(c)
        assert front_curves, "no front curve"
        gmsh.option.setNumber("Mesh.MeshSizeMax", h_far)
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.2 * (h_far if h_front is None else h_front))
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        if h_front is not None:
            f = gmsh.model.mesh.field
            fields = [graded_towards("CurvesList", front_curves, 400, h_front, h_far, 2 * h_front)]
            if h_surf is not None:
                fields.append(graded_towards("SurfacesList", cut_surfs, 100, h_surf, h_far, 3e-3))
            mn = f.add("Min")
            f.setNumbers(mn, "FieldsList", fields)
            f.setAsBackgroundMesh(mn)
        points, tets, index = generate_tets()
        cut_nodes = set()
        for s in cut_surfs:
            nt, _, _ = gmsh.model.mesh.getNodes(2, s, includeBoundary=True)
            cut_nodes.update(int(t) for t in nt)
        front_nodes = set()
        for c in front_curves:
            nt, _, _ = gmsh.model.mesh.getNodes(1, c, includeBoundary=True)
            front_nodes.update(int(t) for t in nt)
        dup_tags = sorted(cut_nodes - front_nodes)
        on_cut = np.zeros(len(points), bool)
        on_cut[[index[t] for t in dup_tags]] = True
        front_mask = np.zeros(len(points), bool)
        front_mask[[index[t] for t in front_nodes]] = True
    finally:
        gmsh.finalize()
    points, tets, used = used_nodes(points, tets)
    on_cut, front_mask = on_cut[used], front_mask[used]
    # duplicate on the + side
    phi = (points - origin) @ n
    assert np.abs(phi[on_cut]).max() < 1e-8, "cut node off the plane"
    centroid_phi = phi[tets].mean(axis=1)
    new_index = -np.ones(len(points), dtype=np.int64)
    cn = np.flatnonzero(on_cut)
    new_index[cn] = len(points) + np.arange(len(cn))
    tets2 = tets.copy()
    plus = centroid_phi > 0
    for e in np.flatnonzero(plus & on_cut[tets].any(axis=1)):
        for k in range(4):
            m = new_index[tets2[e, k]]
            if m >= 0:
                tets2[e, k] = m
    points2 = np.vstack([points, points[cn]])
    info = check(sc, points2, tets2, len(cn), front_mask.sum())
    meshio.write(path, meshio.Mesh(points2, [("tetra", tets2)]), file_format="gmsh", binary=False)
    info.update({"h_far": h_far, "h_front": h_front, "nodes": int(len(points2)), "tets": int(len(tets2)),
                 "duplicated": int(len(cn)), "front_nodes": int(front_mask.sum())})
    return info


def check(sc, points, tets, n_dup, n_front) -> dict:
    origin, u, v = sc["origin"], sc["u"], sc["v"]
    n = np.cross(u, v)
    n /= np.linalg.norm(n)
    p = points[tets]
    vol = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6
    assert np.all(np.abs(vol) > 0), "degenerate tet"
    vsum = np.abs(vol).sum()
    assert abs(vsum - np.prod(BOX)) < 1e-12, f"volumes {vsum} != box {np.prod(BOX)}"
    phi = (p - origin) @ n
    tol = 1e-10
    # tets with vertices strictly on both sides of the plane must not cross the patch:
    span = np.flatnonzero((phi.min(axis=1) < -tol) & (phi.max(axis=1) > tol))
    G = np.array([[u @ u, u @ v], [u @ v, v @ v]])
    bad = 0
    for e in span:
        xs = []
        for a, b in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]:
            fa, fb = phi[e, a], phi[e, b]
            if (fa < -tol and fb > tol) or (fa > tol and fb < -tol):
                t = fa / (fa - fb)
                xs.append(p[e, a] + t * (p[e, b] - p[e, a]))
            elif abs(fa) <= tol:
                xs.append(p[e, a])
        c = np.mean(xs, axis=0) - origin
        st = np.linalg.solve(G, [c @ u, c @ v])
        if np.all(st > 1e-6) and np.all(st < 1 - 1e-6):
            bad += 1
    assert bad == 0, f"{bad} tets cross the patch"
    # the two sides share no duplicated node
    nn = len(points) - n_dup
    orig_users = np.unique(tets[tets < nn])
    copy_users = np.unique(tets[tets >= nn])
    assert len(copy_users) == n_dup
    cphi = phi.mean(axis=1)
    has_copy = (tets >= nn).any(axis=1)
    assert np.all(cphi[has_copy] > 0), "a copy used below"
    return {"volume": float(vsum), "spanning_tets_checked": int(len(span))}


# ---------------------------------------------------------------- case files
def fmt(a) -> str:
    return "[" + ", ".join(f"{x:.17g}" for x in a) + "]"


def case_text(sc: dict, name: str, element: str, mesh: list[str] | None, cut: dict | None) -> str:
    lines = [f'name = "{name}"', "[body]"]
    if mesh is None:
        lines += ["box = [[0.0, 0.0, 0.0], [0.03, 0.06, 0.2]]",
                  "levels = [[2, 4, 13], [4, 8, 27], [8, 16, 53], [12, 24, 80]]"]
    else:
        lines += ["mesh = [" + ", ".join(f'"{m}"' for m in mesh) + "]"]
    lines += [f'element = "{element}"', "[material]", f"young = {sc['young']:.17g}", f"poisson = {sc['nu']:.17g}",
              "density = 1070.0"]
    if cut is not None:
        lines += ["[[cut]]", f"origin = {fmt(sc['origin'])}", f"u = {fmt(sc['u'])}", f"v = {fmt(sc['v'])}"]
        for k, val in cut.items():
            lines.append(f'{k} = "{val}"' if isinstance(val, str) else f"{k} = {val!r}")
    lines += ["[[fix]]", "min = [-inf, -inf, 0.0]", "max = [inf, inf, 0.0]", "displacement = [0.0, 0.0, 0.0]"]
    if sc["load"] == "gravity":
        lines += ["[gravity]", f"acceleration = {fmt(sc['gravity'])}"]
    else:
        lines += ["[[fix]]", "min = [-inf, -inf, 0.2]", "max = [inf, inf, 0.2]", f"displacement = {fmt(sc['top'])}"]
    lines += ["[analysis]", 'type = "static"', 'formulation = "linear"', "[[probe]]",
              "points = [" + ", ".join(fmt(p) for p in probes(sc)) + "]"]
    return "\n".join(lines) + "\n"
