#!/usr/bin/python3
"""Pictures of a case, headless (matplotlib, Agg): the X-FEM solution with its cut opened beside
the graded fine reference, both deformed at true scale.

Left: `xfem-cut run` output (`result.vtu`: uncut elements, and the cut elements as their sub-tets
displaced by their own side, so the crack opens), coloured by |u - u_ref|, u_ref the fine
reference read on the same side of the cut. Right: the pre-cut reference (FEniCSx P2 on the graded
mesh, vertex triangles), coloured by |u|. Only the outer faces of the box and the faces on the cut
patch are drawn (selected on the undeformed geometry), so no inner face shows through.

Usage: pictures.py CASE RESULT_VTU REFERENCE_P2_VTU OUT_PNG [--title TEXT]
"""
from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import meshio  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import cm, colors  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from common import load_case  # noqa: E402
from own_error import Located, read_vtu  # noqa: E402

FACES = [(1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2)]


def box_of(case: dict) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = case["body"]["box"]
    return np.array(lo, float), np.array(hi, float)


def on_surface(x: np.ndarray, lo: np.ndarray, hi: np.ndarray, cuts: list[dict], tol: float = 1e-9) -> np.ndarray:
    """Faces (f x 3 x 3 undeformed vertices) that lie on a box face or on a cut patch."""
    keep = np.zeros(len(x), dtype=bool)
    for k in range(3):
        for v in (lo[k], hi[k]):
            keep |= np.all(np.abs(x[:, :, k] - v) < tol, axis=1)
    for c in cuts:
        o, u, w = (np.array(c[k], float) for k in ("origin", "u", "v"))
        n = np.cross(u, w)
        n /= np.linalg.norm(n)
        d = x - o
        s, t = d @ u / (u @ u), d @ w / (w @ w)
        inside = np.all((np.abs(d @ n) < tol) & (s > -tol) & (s < 1 + tol) & (t > -tol) & (t < 1 + tol), axis=1)
        keep |= inside
    return keep


def surface(points: np.ndarray, cells: np.ndarray, keep_fn) -> tuple[np.ndarray, np.ndarray]:
    """(cell, local face) pairs of the faces kept by keep_fn on the undeformed vertices."""
    tri = np.array([cells[:, list(f)] for f in FACES]).transpose(1, 0, 2).reshape(-1, 3)
    owner = np.repeat(np.arange(len(cells)), 4)
    keep = keep_fn(points[tri])
    return tri[keep], owner[keep]


def draw(ax, verts: np.ndarray, values: np.ndarray, norm, cmap, title: str, lo: np.ndarray, hi: np.ndarray) -> None:
    coll = Poly3DCollection(verts, facecolors=cmap(norm(values)), edgecolors=(0, 0, 0, 0.15), linewidths=0.1)
    ax.add_collection3d(coll)
    allv = verts.reshape(-1, 3)
    mn, mx = np.minimum(allv.min(axis=0), lo), np.maximum(allv.max(axis=0), hi)
    pad = 0.02 * (mx - mn).max()
    mn, mx = mn - pad, mx + pad
    ax.set_xlim(mn[0], mx[0])
    ax.set_ylim(mn[1], mx[1])
    ax.set_zlim(mn[2], mx[2])
    ax.set_box_aspect(tuple(mx - mn), zoom=1.2)  # true proportions
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(3))
    ax.view_init(elev=18, azim=-125)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_title(title, fontsize=10)


def save(fig, out: Path) -> None:
    """Writes the figure whole or not at all (a temporary file renamed onto `out`)."""
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_suffix(".tmp.png")
    fig.savefig(tmp)
    tmp.replace(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("case")
    ap.add_argument("result", type=Path)
    ap.add_argument("reference", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--title", default="")
    a = ap.parse_args()
    case = load_case(a.case)
    lo, hi = box_of(case)
    cuts = case.get("cut", [])
    keep = lambda x: on_surface(x, lo, hi, cuts)

    # X-FEM picture: tets only (VTK 10) or Tet10 (their vertices).
    m = meshio.read(a.result)
    cells = np.vstack([c.data[:, :4] for c in m.cells if c.type in ("tetra", "tetra10")])
    xp, up = m.points, m.point_data["u"]
    tri, owner = surface(xp, cells, keep)
    # Each face's centroid, read just inside its own cell, so a face on the cut takes its side.
    fc = xp[tri].mean(axis=1)
    cc = xp[cells[owner]].mean(axis=1)
    probe = fc + 1e-3 * (cc - fc)
    rp, rc, ru = read_vtu(a.reference)
    ref = Located(rp, rc, ru)
    u_ref = ref.values(probe)
    u_face = up[tri].mean(axis=1)
    err = np.linalg.norm(u_face - u_ref, axis=1) * 1e3
    if np.isnan(err).any():
        raise SystemExit(f"error: {int(np.isnan(err).sum())} faces not found in the reference")
    xfem_verts = xp[tri] + up[tri]

    # The reference: its outer and crack faces (vertex triangles of the P2 cells).
    rtri, rown = surface(rp, rc[:, :4], keep)
    ref_verts = rp[rtri] + ru[rtri]
    ref_mag = np.linalg.norm(ru[rtri].mean(axis=1), axis=1) * 1e3

    fig = plt.figure(figsize=(12, 8), dpi=100)
    ax1 = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2, projection="3d")
    n1 = colors.Normalize(0, max(err.max(), 1e-12))
    n2 = colors.Normalize(0, ref_mag.max())
    draw(ax1, xfem_verts, err, n1, cm.magma, f"X-FEM, cut opened ({len(tri)} faces)\ncolour: |u - u_ref| (mm)", lo, hi)
    draw(ax2, ref_verts, ref_mag, n2, cm.viridis, f"reference: FEniCSx P2, graded pre-cut mesh\ncolour: |u| (mm)", lo, hi)
    fig.colorbar(cm.ScalarMappable(norm=n1, cmap=cm.magma), ax=ax1, shrink=0.6, label="|u - u_ref| (mm)")
    fig.colorbar(cm.ScalarMappable(norm=n2, cmap=cm.viridis), ax=ax2, shrink=0.6, label="|u| (mm)")
    fig.suptitle(a.title or a.case)
    save(fig, a.out)
    print(f"{a.out}: {len(tri)} X-FEM faces (max |u - u_ref| {err.max():.3g} mm), {len(rtri)} reference faces (max |u| {ref_mag.max():.3g} mm)")


if __name__ == "__main__":
    main()
