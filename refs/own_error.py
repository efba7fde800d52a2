#!/usr/bin/python3
"""The reference's own error: the fine graded P2 reference against the 1.4x coarser one.

Same measures as the study (`xfem-cut converge`), with the coarse reference in the place of a
solution: the L2 difference integrated with the degree-5 rule on the fine mesh, relative to the
fine solution's norm; the crack opening [u] sampled on the cut patch (12 x 24 points, each side
read 1e-8 m off the plane); the largest probe difference relative to the largest probe
displacement (probes on the cut read on its + side). Points are located by barycentric
coordinates among the nearest tets (centroid k-d tree), never by nearest node, so the two
faces of a crack, whose nodes coincide, are told apart by the side of the point.
"""
from __future__ import annotations

import argparse
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from common import EDGES, load_case, write_json

# Degree-5 rule (Walkington, 14 points), as src/quadrature.rs: (barycentric pattern, weight).
_A5, _B5, _C5 = 0.0927352503108912, 0.3108859192633006, 0.0455037041256496
_W = (0.0734930431163619, 0.1126879257180158, 0.0425460207770812)


def degree5() -> tuple[np.ndarray, np.ndarray]:
    pts, w = [], []
    for a, wa in ((_A5, _W[0]), (_B5, _W[1])):
        for k in range(4):
            l = np.full(4, a)
            l[k] = 1 - 3 * a
            pts.append(l)
            w.append(wa)
    for i, j in [(2, 3), (1, 3), (1, 2), (0, 3), (0, 2), (0, 1)]:
        l = np.full(4, _C5)
        l[i] = l[j] = 0.5 - _C5
        pts.append(l)
        w.append(_W[2])
    return np.array(pts), np.array(w)


def read_vtu(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points, cells (10 nodes, VTK order) and point data `u` of a VTU written by common.write_vtu."""
    root = ET.parse(path).getroot()
    arrays = {a.get("Name"): a.text for a in root.iter("DataArray")}
    points = np.array(arrays["Points"].split(), dtype=float).reshape(-1, 3)
    conn = np.array(arrays["connectivity"].split(), dtype=np.int64)
    u = np.array(arrays["u"].split(), dtype=float).reshape(-1, 3)
    return points, conn.reshape(-1, 10), u


def shape_p2(l: np.ndarray) -> np.ndarray:
    """Tet10 shape functions at barycentric points l (n x 4) -> n x 10."""
    n = np.empty((len(l), 10))
    n[:, :4] = l * (2 * l - 1)
    for k, (a, b) in enumerate(EDGES):
        n[:, 4 + k] = 4 * l[:, a] * l[:, b]
    return n


class Located:
    """Point location in a Tet10 mesh by barycentric coordinates of the vertex tet."""

    def __init__(self, points: np.ndarray, cells: np.ndarray, u: np.ndarray):
        self.points, self.cells, self.u = points, cells, u
        p = points[cells[:, :4]]
        self.p0 = p[:, 0]
        t = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]], axis=2)
        self.tinv = np.linalg.inv(t)
        self.tree = cKDTree(p.mean(axis=1))

    def bary(self, cand: np.ndarray, x: np.ndarray) -> np.ndarray:
        l123 = np.einsum("nkij,nkj->nki", self.tinv[cand], x[:, None, :] - self.p0[cand])
        return np.concatenate([1 - l123.sum(axis=2, keepdims=True), l123], axis=2)

    def values(self, x: np.ndarray, tol: float = 1e-10) -> np.ndarray:
        out = np.full((len(x), 3), np.nan)
        for s in range(0, len(x), 50_000):
            xs = x[s:s + 50_000]
            todo = np.arange(len(xs))
            for k in (16, 64, 256):
                if len(todo) == 0:
                    break
                _, cand = self.tree.query(xs[todo], k=k)
                l = self.bary(cand, xs[todo])
                inside = l.min(axis=2) >= -tol
                has = inside.any(axis=1)
                first = inside.argmax(axis=1)
                rows = todo[has]
                e = cand[has, first[has]]
                lb = l[has, first[has]]
                out[s + rows] = np.einsum("nk,nkc->nc", shape_p2(lb), self.u[self.cells[e]])
                todo = todo[~has]
        return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("case")
    ap.add_argument("fine", type=Path)
    ap.add_argument("coarse", type=Path)
    ap.add_argument("out", type=Path)
    a = ap.parse_args()
    case = load_case(a.case)
    fp, fc, fu = read_vtu(a.fine)
    cp, cc, cu = read_vtu(a.coarse)
    fine, coarse = Located(fp, fc, fu), Located(cp, cc, cu)

    # L2 over the fine mesh (degree 5), the coarse field located at its quadrature points.
    lq, wq = degree5()
    pv = fp[fc[:, :4]]
    vol = np.abs(np.einsum("ij,ij->i", np.cross(pv[:, 1] - pv[:, 0], pv[:, 2] - pv[:, 0]), pv[:, 3] - pv[:, 0])) / 6
    xq = np.einsum("qk,ekc->eqc", lq, pv).reshape(-1, 3)
    uf = np.einsum("qk,ekc->eqc", shape_p2(lq), fu[fc]).reshape(-1, 3)
    uc = coarse.values(xq)
    missed = int(np.isnan(uc[:, 0]).sum())
    if missed:
        raise SystemExit(f"error: {missed} quadrature points of the fine mesh not found in the coarse one")
    w = (vol[:, None] * wq[None, :]).reshape(-1)
    l2 = float(np.sqrt(np.sum(w * np.sum((uf - uc) ** 2, axis=1)) / np.sum(w * np.sum(uf ** 2, axis=1))))

    result = {"l2_rel": l2, "opening_rel": None, "probe_rel": None}
    cut = (case.get("cut") or [None])[0]
    normal = None
    if cut is not None:
        o, cu_, cv_ = (np.array(cut[k], float) for k in ("origin", "u", "v"))
        normal = np.cross(cu_, cv_)
        normal /= np.linalg.norm(normal)
        ns, nt = 12, 24
        xs = np.array([o + cu_ * ((i + 0.5) / ns) + cv_ * ((j + 0.5) / nt) for i in range(ns) for j in range(nt)])
        off = normal * 1e-8
        jf = fine.values(xs + off) - fine.values(xs - off)
        jc = coarse.values(xs + off) - coarse.values(xs - off)
        ok = ~np.isnan(jf[:, 0])
        result["opening_rel"] = float(np.sqrt(np.sum((jc[ok] - jf[ok]) ** 2) / np.sum(jf[ok] ** 2)))
        result["opening_points"] = int(ok.sum())
    probes = np.array([p for pr in case.get("probe", []) for p in pr["points"]], float).reshape(-1, 3)
    if len(probes):
        if normal is not None:
            lev = (probes - o) @ normal
            s = (probes - o) @ cu_ / (cu_ @ cu_)
            t = (probes - o) @ cv_ / (cv_ @ cv_)
            on_cut = (np.abs(lev) < 1e-12) & (s >= -1e-9) & (s <= 1 + 1e-9) & (t >= -1e-9) & (t <= 1 + 1e-9)
            probes = probes + np.where(on_cut[:, None], normal * 1e-8, 0.0)
        pf, pc = fine.values(probes), coarse.values(probes)
        ok = ~np.isnan(pf[:, 0])
        result["probe_rel"] = float(np.max(np.linalg.norm(pc[ok] - pf[ok], axis=1)) / np.max(np.linalg.norm(pf[ok], axis=1)))
    result["fine"], result["coarse"] = str(a.fine.parent.name), str(a.coarse.parent.name)
    write_json(a.out, result)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
