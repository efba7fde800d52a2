#!/usr/bin/python3
"""Frames of a blade scene as the blade cuts, headless (matplotlib, Agg): the body's outer faces
and the faces on the swept cut, deformed (optionally magnified) and coloured by |u|, the blade's
edge drawn where it is at each frame.

Reads `xfem-cut run`'s `result.pvd` series of a case with one straight blade (`blade`, `travel`,
`start`, `end`): each frame's `.vtu` holds the tetrahedra (a cut element drawn as its sub-tets,
each displaced by its own side, so the cut opens behind the blade) and the blade's edge as a
line cell. The faces drawn are selected on the undeformed geometry: those on the box and those on
the part of the cut the blade has swept by the frame's time.

Usage: sweep_pictures.py CASE RESULT_PVD OUT_PNG [--times T ...] [--scale S] [--title TEXT]
"""
from __future__ import annotations

import argparse
import xml.etree.ElementTree as ET
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import meshio  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import cm, colors  # noqa: E402

from common import load_case  # noqa: E402
from pictures import box_of, draw, on_surface, save, surface  # noqa: E402


def frames(pvd: Path) -> list[tuple[float, Path]]:
    """(time, vtu path) of each data set of a `.pvd` collection, in time order."""
    root = ET.parse(pvd).getroot()
    out = [(float(d.get("timestep")), pvd.parent / d.get("file")) for d in root.iter("DataSet")]
    return sorted(out)


def swept(blade: dict, t: float) -> dict:
    """The patch (origin, u, v) a straight blade has swept by time t."""
    a, b = (np.array(p, float) for p in blade["blade"])
    travel = np.array(blade["travel"], float)
    s = np.clip((t - blade["start"]) / (blade["end"] - blade["start"]), 0.0, 1.0)
    return {"origin": a, "u": b - a, "v": travel * s}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("case")
    ap.add_argument("pvd", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--times", type=float, nargs="+", default=[0.1, 0.3, 0.5, 0.6, 3.0],
                    help="simulated times to draw (the nearest frame each)")
    ap.add_argument("--scale", type=float, default=1.0, help="displacement magnification")
    ap.add_argument("--title", default="")
    a = ap.parse_args()
    case = load_case(a.case)
    lo, hi = box_of(case)
    blades = [c for c in case.get("cut", []) if "blade" in c]
    if len(blades) != 1 or "travel" not in blades[0]:
        raise SystemExit(f"error: {a.case}: sweep_pictures.py draws one straight blade (blade + travel), found {len(blades)}")
    blade = blades[0]
    series = frames(a.pvd)
    if not series:
        raise SystemExit(f"error: {a.pvd}: no data sets")
    chosen = [min(series, key=lambda f: abs(f[0] - t)) for t in a.times]

    drawn = []
    for t, path in chosen:
        m = meshio.read(path)
        cells = np.vstack([c.data[:, :4] for c in m.cells if c.type in ("tetra", "tetra10")])
        lines = [c.data for c in m.cells if c.type == "line"]
        xp, up = m.points, m.point_data["u"]
        cut = swept(blade, t)
        keep = lambda x, cut=cut: on_surface(x, lo, hi, [cut] if np.linalg.norm(cut["v"]) > 0 else [])
        tri, _ = surface(xp, cells, keep)
        verts = xp[tri] + a.scale * up[tri]
        mag = np.linalg.norm(up[tri].mean(axis=1), axis=1) * 1e3
        edge = None
        if lines:
            # The edge within the body, moved with the body: each end takes the displacement
            # of the mesh point nearest it (the cut is swept in the reference configuration).
            e0, e1 = xp[lines[0][0]]
            ends = []
            for s_ in np.linspace(0.0, 1.0, 201):
                x = e0 + s_ * (e1 - e0)
                if np.all(x >= lo - 1e-12) and np.all(x <= hi + 1e-12):
                    ends.append(x)
            if ends:
                ends = np.array([ends[0], ends[-1]])
                near = [np.argmin(np.linalg.norm(xp - x, axis=1)) for x in ends]
                edge = ends + a.scale * up[near]
        drawn.append((t, verts, mag, edge))
    top = max(d[2].max() for d in drawn) or 1.0
    allv = np.vstack([d[1].reshape(-1, 3) for d in drawn])
    mn, mx = np.minimum(allv.min(axis=0), lo), np.maximum(allv.max(axis=0), hi)
    norm = colors.Normalize(0, top)

    fig = plt.figure(figsize=(3.4 * len(drawn) + 1.0, 6.0), dpi=100)
    for k, (t, verts, mag, edge) in enumerate(drawn):
        ax = fig.add_subplot(1, len(drawn), k + 1, projection="3d")
        draw(ax, verts, mag, norm, cm.viridis, f"t = {t:.2f} s", mn, mx)
        if edge is not None:
            # Inside the body: drawn over the faces (a 3-D axis would sort it behind them).
            ax.computed_zorder = False
            ax.plot(edge[:, 0], edge[:, 1], edge[:, 2], color="red", linewidth=3, zorder=5)
    fig.subplots_adjust(left=0.02, right=0.9, bottom=0.02, top=0.88, wspace=0.05)
    bar = fig.add_axes((0.92, 0.2, 0.012, 0.55))
    fig.colorbar(cm.ScalarMappable(norm=norm, cmap=cm.viridis), cax=bar, label="|u| (mm)")
    scale = "true scale" if a.scale == 1.0 else f"displacements ×{a.scale:g}"
    fig.suptitle(a.title or f"{case.get('name', a.case)}: the blade (red) and the cut opening behind it ({scale})")
    save(fig, a.out)
    print(f"{a.out}: frames at t = {', '.join(f'{d[0]:.2f}' for d in drawn)} s, max |u| {top:.3g} mm ({scale})")


if __name__ == "__main__":
    main()
