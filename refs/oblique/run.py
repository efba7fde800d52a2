#!/usr/bin/python3
"""Random oblique crack fronts against remeshed references (`make oblique`): per scene, X-FEM
(tip, geometric tip, extend; Tet4 and Tet10 on the structured box levels) and pre-cut FEM on
uniform gmsh meshes, each against our Tet10 solution on a graded pre-cut mesh (the solver equals
FEniCSx on the same mesh, tests/references.rs), whose own error is its difference from a 1.4x
coarser graded one. Max / rms probe errors per level, and whether they fall at every level.

Usage: /usr/bin/python3 run.py [seed ...]  (default: the 8 scenes of SCENES). Cached: reruns only
what is missing; delete refs/out/oblique/sNN to redo a scene. Writes refs/out/oblique/summary.txt."""
from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from scene import case_text, mesh_precut, sample_scene  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
BIN = str(REPO / "target" / "release" / "xfem-cut")
ROOT = REPO / "refs" / "out" / "oblique"
SCENES = [(11, "edge"), (12, "edge"), (13, "inside"), (14, "corner"), (15, "edge"), (16, "inside"), (17, "corner"), (18, "edge")]
REF = (0.003, 0.0005, 0.0012)       # h_far, h_front, h_surf
REFC = tuple(1.4 * h for h in REF)  # coarser graded reference (own-error estimate)
UNIFORM = [0.006, 0.004, 0.003]
VARIANTS = {"tip": {}, "geo": {"tip_radius": 0.004}, "ext": {"front": "extend"}}
XLEVELS = {"tet4": [0, 1, 2, 3], "tet10": [0, 1, 2]}  # tet10 L3 (596k DOFs) takes ~120 s: left out
PCLEVELS = {"tet4": [0, 1, 2], "tet10": [0, 1, 2]}


def run_case(d: Path, case: str, level: int) -> dict:
    out = d / "out" / f"{case}_L{level}"
    log = out.with_suffix(".log")
    if not (out / "probes.csv").exists():
        out.parent.mkdir(parents=True, exist_ok=True)
        t = time.time()
        p = subprocess.run([BIN, "run", str(d / f"{case}.toml"), "--level", str(level), "--out", str(out)],
                           capture_output=True, text=True, timeout=300)
        wall = time.time() - t
        log.write_text(p.stdout + "\n--stderr--\n" + p.stderr + f"\n--rc-- {p.returncode}\n--wall-- {wall:.2f}\n")
        if p.returncode != 0:
            return {"error": (p.stderr.strip() or p.stdout.strip()).splitlines()[-1:] , "rc": p.returncode}
    text = log.read_text() if log.exists() else ""
    m = re.search(r"(\d+) DOFs", text)
    w = re.search(r"--wall-- ([\d.]+)", text)
    u = np.loadtxt(out / "probes.csv", delimiter=",", skiprows=1)
    return {"dofs": int(m.group(1)) if m else None, "u": u[:, 3:6], "wall": float(w.group(1)) if w else None}


NEAR = slice(4, 11)  # probes 1.5-2.5 mm from the cut / front (scene.probes order)


def err(u, ref):
    """(max, rms, near): max_p |u-u_ref| / max_p |u_ref|, its rms version, and the max version over
    the near-cut probes only."""
    d = np.linalg.norm(u - ref, axis=1)
    r = np.linalg.norm(ref, axis=1)
    return (float(d.max() / r.max()), float(np.sqrt(np.mean(d ** 2) / np.mean(r ** 2))),
            float(d[NEAR].max() / r[NEAR].max()))


def do_scene(seed: int, kind: str) -> dict:
    sc = sample_scene(seed, kind)
    d = ROOT / f"s{seed}"
    d.mkdir(parents=True, exist_ok=True)
    print(f"\n=== scene seed {seed} ({kind}): E={sc['young']:.4g} nu={sc['nu']:.3f} load={sc['load']} "
          + (f"g={np.round(sc['gravity'], 3).tolist()}" if sc['load'] == 'gravity' else f"top={np.round(sc['top'], 5).tolist()}"))
    print(f"    patch origin={np.round(sc['origin'], 5).tolist()} u={np.round(sc['u'], 5).tolist()} "
          f"v={np.round(sc['v'], 5).tolist()} n={np.round(sc['n'], 3).tolist()} cut area in body={sc['area'] * 1e6:.0f} mm^2, "
          f"front segments={len(sc['front'])}, front length={sum(np.linalg.norm(s[1] - s[0]) for s in sc['front']) * 1e3:.1f} mm", flush=True)
    meshes = {"ref": REF, "refc": REFC, **{f"u{int(h * 1e3)}": (h, None, None) for h in UNIFORM}}
    minfo = {}
    for name, (hf, hfr, hs) in meshes.items():
        path = d / f"{name}.msh"
        ij = path.with_suffix(".json")
        if not ij.exists():
            t = time.time()
            info = mesh_precut(sc, hf, hfr, path, hs)
            info["mesh_s"] = time.time() - t
            ij.write_text(json.dumps(info))
        minfo[name] = json.loads(ij.read_text())
    print("    meshes: " + "; ".join(f"{k}: {v['nodes']} nodes {v['tets']} tets dup {v['duplicated']} front {v['front_nodes']}"
                                    for k, v in minfo.items()), flush=True)
    cases = {"ref": ("tet10", ["ref.msh"], None), "refc": ("tet10", ["refc.msh"], None)}
    for el in ("tet4", "tet10"):
        cases[f"fem_{el}"] = (el, [f"u{int(h * 1e3)}.msh" for h in UNIFORM], None)
        for var, cut in VARIANTS.items():
            cases[f"x{var}_{el}"] = (el, None, cut)
    for name, (el, mesh, cut) in cases.items():
        (d / f"{name}.toml").write_text(case_text(sc, f"s{seed}_{name}", el, mesh, cut))
    res = {"seed": seed, "kind": kind, "rows": []}
    ref = run_case(d, "ref", 0)
    if "error" in ref:
        print(f"    REFERENCE FAILED: {ref}")
        return res
    refc = run_case(d, "refc", 0)
    e = err(refc["u"], ref["u"]) if "u" in refc else (np.nan, np.nan, np.nan)
    print(f"    reference: {ref['dofs']} DOFs ({ref['wall']:.1f} s); coarser graded ({refc.get('dofs')} DOFs) vs ref: "
          f"max {e[0]:.2e} rms {e[1]:.2e} near {e[2]:.2e}   |u_ref|max={np.linalg.norm(ref['u'], axis=1).max():.3e} m", flush=True)
    res["ref"] = {"dofs": ref["dofs"], "own_max": e[0], "own_rms": e[1], "own_near": e[2], "wall": ref["wall"]}
    plan = []
    for el in ("tet4", "tet10"):
        plan.append((f"fem_{el}", el, PCLEVELS[el]))
        for var in VARIANTS:
            plan.append((f"x{var}_{el}", el, XLEVELS[el]))
    print(f"    {'variant':10s} {'elem':5s} | " + " | ".join(f"L{k}: DOFs  max    rms     near    " for k in range(4)) + "| max monotone")
    for case, el, levels in plan:
        cells, maxes = [], []
        for k in levels:
            r = run_case(d, case, k)
            if "error" in r:
                cells.append(f"L{k}: ERROR rc={r['rc']} {r['error']}")
                res["rows"].append({"case": case, "level": k, "error": r["error"], "rc": r["rc"]})
                print(f"    !! {d / (case + '.toml')} --level {k}: rc={r['rc']} {r['error']}", flush=True)
                continue
            em, er, en = err(r["u"], ref["u"])
            maxes.append(em)
            cells.append(f"{r['dofs']:7d} {em:.2e} {er:.2e} {en:.2e}")
            res["rows"].append({"case": case, "level": k, "dofs": r["dofs"], "max": em, "rms": er, "near": en, "wall": r["wall"]})
        mono = all(b < a for a, b in zip(maxes, maxes[1:]))
        print(f"    {case.split('_')[0]:10s} {el:5s} | " + " | ".join(cells) + f" | {'yes' if mono else 'NO'}", flush=True)
    (d / "results.json").write_text(json.dumps(res, indent=1))
    return res


def summary() -> str:
    """Max probe error per level of every scene run so far, and whether it falls at every level."""
    out = []
    for f in sorted(ROOT.glob("s*/results.json")):
        r = json.loads(f.read_text())
        ref = r.get("ref", {})
        out.append(f"s{r['seed']} {r['kind']:6s} reference {ref.get('dofs')} DOFs, own error (against 1.4x coarser "
                   f"graded): max {ref.get('own_max', float('nan')):.1e} near {ref.get('own_near', float('nan')):.1e}")
        by: dict[str, list] = {}
        for x in r["rows"]:
            by.setdefault(x["case"], []).append(x)
        for case, xs in by.items():
            m = [x["max"] for x in xs if "max" in x]
            falls = all(b < a for a, b in zip(m, m[1:])) and len(m) == len(xs)
            out.append(f"   {case:10s} " + "  ".join(f"{x['dofs']:>6d}:{x['max']:.1e}" if "max" in x else f"ERROR {x['error']}"
                                                  for x in xs) + ("" if falls else "  DOES NOT FALL AT EVERY LEVEL"))
    return "\n".join(out) + "\n"


def main():
    seeds = [int(a) for a in sys.argv[1:]] or [s for s, _ in SCENES]
    kinds = dict(SCENES)
    for s in seeds:
        do_scene(s, kinds.get(s, "edge"))
    text = summary()
    (ROOT / "summary.txt").write_text(text)
    print("\n" + text, end="")


if __name__ == "__main__":
    main()
