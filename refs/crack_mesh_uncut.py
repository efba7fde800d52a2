#!/usr/bin/python3
"""The crack mesh of the seed's beam (`mesh.py beam_crack`) with its crack's nodes shared, not
duplicated: the same nodes and tets as the pre-cut mesh of that size, the crack's faces and front
line mesh faces and edges but the body whole. X-FEM on it with the extended front equals FEM on the
pre-cut mesh, so the tip front can be set beside remeshed FEM on one mesh
(`examples/error_map.rs CASE tip|extend LEVEL mesh=DIR`). Kept apart from mesh.py, whose hash is
an input of every reference.

    /usr/bin/python3 refs/crack_mesh_uncut.py 0.006 OUT/L2.msh   # h of the level: out/meshes/beam_crack/L2.json
"""
from __future__ import annotations

import argparse
from pathlib import Path

from mesh import check, generate, write_msh


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("h", type=float, help="mesh size (m), as the level's h_far")
    ap.add_argument("out", type=Path)
    a = ap.parse_args()
    points, tets = generate("beam_crack", a.h)
    check("beam_crack", points, tets, 0)
    write_msh(a.out, points, tets)
    print(f"{a.out}: {len(points)} nodes, {len(tets)} tets")


if __name__ == "__main__":
    main()
