#!/usr/bin/env python3
"""Static linear solve, ours against FEniCSx at equal cores, 10k to 400k DOFs.

The `gravity` case on pre-cut beam meshes (gmsh, `mesh.py beam_crack H`), Tet4 against P1 and
Tet10 against P2, on 1 and 2 cores:
- ours: `xfem-cut run` with `XFEM_THREADS=c` (numeric factorisation and element loops on c
  threads; on 2, the ordering and symbolic factorisation beside the element scatter maps, and the
  factor split in two halves factorised side by side); time = element data + pattern + symbolic +
  numeric factorisation + solve, as the run prints them (the mesh read is not counted, as for
  FEniCSx);
- FEniCSx (dolfinx 0.5.2, MUMPS, OpenBLAS): `solve_fenicsx.py`, time = assembly + solve (JIT
  excluded, as it times them); on c cores as one rank with OPENBLAS_NUM_THREADS = OMP_NUM_THREADS
  = c, and for c = 2 also as two MPI ranks of one thread each; the faster is the comparison.
Peak memory is the process's maximum resident set (wait4), for the single-process runs. Runs under
5 s are repeated three times and the median kept.

Run it on a quiet machine: `cd refs && /usr/bin/python3 bench_static.py` (about 25 minutes on 2
cores); writes ../reports/data/static_vs_fenicsx.csv, which `xfem-cut report` shows.
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent
PY = "/usr/bin/python3"
BIN = ROOT.parent / "target" / "release" / "xfem-cut"
# Mesh sizes (m) per element: 10k to 400k DOFs.
SIZES = {"tet4": [0.0045, 0.0028, 0.002, 0.0014], "tet10": [0.012, 0.006, 0.0035, 0.0028]}
DEGREE = {"tet4": 1, "tet10": 2}


def run_measured(cmd: list[str], env: dict[str, str]) -> tuple[str, float, float]:
    """Runs `cmd`; returns its stdout, wall seconds and peak RSS (MB) from wait4."""
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as out:
        p = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env={**os.environ, **env}, cwd=ROOT)
        _, status, usage = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
        out.seek(0)
        text = out.read().decode(errors="replace")
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit(f"bench_static: {' '.join(cmd)} failed:\n{text[-2000:]}")
    return text, wall, usage.ru_maxrss / 1024


def case_file(element: str, folder: Path) -> Path:
    """gravity.toml without its cut (FEM on the pre-cut mesh) with `element`."""
    text = (ROOT.parent / "cases" / "gravity.toml").read_text()
    text = re.sub(r"\[\[cut\]\].*?(?=\n\[)", "", text, flags=re.S)
    text = re.sub(r'element = "tet\d+"', f'element = "{element}"', text)
    path = folder / f"gravity_{element}.toml"
    path.write_text(text)
    return path


def ours(case: Path, msh: Path, cores: int, folder: Path) -> dict:
    text, wall, peak = run_measured([str(BIN), "run", str(case), "--mesh", str(msh), "--out", str(folder / "ours")],
                                    {"XFEM_THREADS": str(cores)})
    # On one thread the symbolic factorisation follows the element data; on more it runs beside
    # them, and the run prints their wall time together.
    pre = re.search(r"element data \+ pattern ([\d.]+) ms, symbolic factorisation ([\d.]+) ms", text)
    beside = re.search(r"element data \+ pattern with the symbolic factorisation beside it ([\d.]+) ms", text)
    solve = re.search(r"static: solve ([\d.]+) ms", text)
    dofs = re.search(r"(\d+) free DOFs", text)
    if not ((pre or beside) and solve and dofs):
        sys.exit(f"bench_static: cannot read the run's timings:\n{text}")
    precompute = float(beside[1]) if beside else float(pre[1]) + float(pre[2])
    seconds = (precompute + float(solve[1])) / 1e3
    return {"seconds": seconds, "peak_mb": peak, "dofs": int(dofs[1]), "wall": wall}


def fenicsx(msh: Path, degree: int, cores: int, ranks: int, folder: Path) -> dict:
    target = folder / f"p{degree}_{cores}c_{ranks}r.vtu"
    cmd = [PY, "solve_fenicsx.py", "gravity", str(msh), str(degree), str(target)]
    if ranks > 1:
        cmd = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-n", str(ranks)] + cmd
    threads = str(cores // ranks)
    _, wall, peak = run_measured(cmd, {"OPENBLAS_NUM_THREADS": threads, "OMP_NUM_THREADS": threads})
    info = json.loads(target.with_suffix(".json").read_text())
    return {"seconds": info["assembly_s"] + info["solve_s"], "peak_mb": peak if ranks == 1 else float("nan"),
            "dofs": info["dofs"], "wall": wall}


def median_run(measure, repeats: int = 1) -> dict:
    """The run of median time among `repeats` runs of `measure`."""
    runs = sorted((measure() for _ in range(repeats)), key=lambda r: r["seconds"])
    return runs[len(runs) // 2]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--elements", nargs="*", default=list(SIZES), choices=list(SIZES))
    ap.add_argument("--cores", nargs="*", type=int, default=[1, 2])
    ap.add_argument("--max-h-index", type=int, default=len(SIZES["tet4"]), help="only the first K sizes")
    ap.add_argument("--csv", type=Path, default=ROOT.parent / "reports" / "data" / "static_vs_fenicsx.csv")
    a = ap.parse_args()
    if not BIN.exists():
        sys.exit(f"bench_static: {BIN} missing (cargo build --release)")
    meshes = ROOT / "out" / "bench" / "meshes"
    meshes.mkdir(parents=True, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for element in a.elements:
            case = case_file(element, folder)
            for h in SIZES[element][: a.max_h_index]:
                msh = meshes / f"beam_crack_h{h}.msh"
                if not msh.exists():
                    run_measured([PY, "mesh.py", "beam_crack", str(h), str(msh)], {})
                for cores in a.cores:
                    # Small runs take a fraction of a second: the median of a few repeats.
                    o = median_run(lambda: ours(case, msh, cores, folder))
                    repeats = 3 if o["seconds"] < 5.0 else 1
                    if repeats > 1:
                        o = median_run(lambda: ours(case, msh, cores, folder), repeats)
                    one = median_run(lambda: fenicsx(msh, DEGREE[element], cores, 1, folder), repeats)
                    two = median_run(lambda: fenicsx(msh, DEGREE[element], cores, 2, folder), repeats) if cores == 2 else None
                    best = min([one] + ([two] if two else []), key=lambda r: r["seconds"])
                    row = {
                        "element": element, "h_mm": h * 1e3, "cores": cores,
                        "dofs_ours_free": o["dofs"], "dofs_fenicsx": one["dofs"],
                        "ours_s": round(o["seconds"], 4), "ours_peak_mb": round(o["peak_mb"]),
                        "fenicsx_1rank_s": round(one["seconds"], 4), "fenicsx_1rank_peak_mb": round(one["peak_mb"]),
                        "fenicsx_2ranks_s": round(two["seconds"], 4) if two else "",
                        "speedup": round(best["seconds"] / o["seconds"], 3),
                    }
                    rows.append(row)
                    print(f"  {element} h={h * 1e3:.1f} mm {cores} core(s): {o['dofs']} DOFs, ours {o['seconds']:.2f} s "
                          f"({o['peak_mb']:.0f} MB), FEniCSx {one['seconds']:.2f} s ({one['peak_mb']:.0f} MB)"
                          + (f", 2 ranks {two['seconds']:.2f} s" if two else "") + f": {row['speedup']:.2f}x", flush=True)
    a.csv.parent.mkdir(parents=True, exist_ok=True)
    # Rows of this run replace the same (element, h, cores) rows of an earlier run; the others stay.
    key = lambda r: (r["element"], float(r["h_mm"]), int(r["cores"]))
    if a.csv.exists():
        with a.csv.open() as f:
            done = {key(r) for r in rows}
            rows = [r for r in csv.DictReader(f) if key(r) not in done] + rows
    rows.sort(key=lambda r: (r["element"], -float(r["h_mm"]), int(r["cores"])))
    tmp_csv = a.csv.with_suffix(".csv.tmp")
    with tmp_csv.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    tmp_csv.replace(a.csv)
    print(f"wrote {a.csv}")


if __name__ == "__main__":
    main()
