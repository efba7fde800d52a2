#!/usr/bin/python3
"""Builds every reference the cases need, skipping those whose inputs are unchanged.

Meshes: refs/out/meshes/<family>/L<k>.msh. Solutions: refs/out/<case>/<family>_L<k>/p{1,2}.vtu
(+ .json with DOFs, times, residual). Each output has a .hash file with the hash of its inputs
(scripts, case file, mesh, tool versions, ranks); an output whose hash matches is skipped.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from common import CASES, OUT, ROOT, file_hash, write_json

PY = "/usr/bin/python3"
# Mesh size per level (m).
LEVELS = [0.012, 0.008, 0.006, 0.0045, 0.0035]
# The graded references (P2): (far-field size, size at the singular curves) in m. The finest
# judged level is L4 (3.5 mm): "fine" has 1/4.4 of it at the front and is finer everywhere;
# "fine_coarse" is 1.4x coarser everywhere, and their difference is the reference's own error.
GRADED = {"fine": (0.0032, 0.0008), "fine_coarse": (0.0032 * 1.4, 0.0008 * 1.4)}
# The old reference (uniform 2.8 mm, P2), kept only to state its error against the graded one;
# too big for MUMPS within ~8 GB here, so solved with CG + GAMG (set "uniform").
UNIFORM_FINE = 0.0028
FAMILY = {"gravity": "beam_crack", "stretch": "beam_crack", "bend": "beam_crack", "stretch_face": "beam_crack",
          "bend_face": "beam_crack", "slice": "slice_precut"}
SETS = {
    "test": {"levels": [0, 1], "fine": False},
    "graded": {"levels": list(range(len(LEVELS))), "fine": True, "solve_levels": False},
    "all": {"levels": list(range(len(LEVELS))), "fine": True},
    "uniform": {"levels": [], "fine": False, "uniform": True},
}
VENV_PY = str(ROOT / ".venv" / "bin" / "python")
# Corotational references (scikit-fem): (case, family, level, degree, load steps, load scale,
# tolerance). Newton with the exact tangent (rotation derivative included): 3-4 iterations per
# load step; each Newton system by MUMPS (petsc4py): P2 on L0 about a minute, on L1 about 3 min
# and up to 19 GB (the vectorised tangent).
# L0 in every set (the tests read it); P1 on L1-L2 and P2 on L1 only in the sets with the fine
# references (`make refs`), so the corotational study has an independent reference beyond L0.
COROT = [(case, "beam_crack", level, degree, 20, 1.0, 1e-11)
         for degree, levels in ((1, ("L0", "L1", "L2")), (2, ("L0", "L1")))
         for level in levels
         for case in ("stretch_face", "bend_face")]


def tool_versions() -> str:
    code = ("import gmsh, dolfinx, meshio; gmsh.initialize(); "
            "print('gmsh', gmsh.option.getString('General.Version'), 'dolfinx', dolfinx.__version__, 'meshio', meshio.__version__); "
            "gmsh.finalize()")
    return subprocess.run([PY, "-c", code], capture_output=True, text=True).stdout.strip()


def up_to_date(target: Path, h: str) -> bool:
    hf = target.with_name(target.name + ".hash")
    return target.exists() and hf.exists() and hf.read_text() == h


def mark(target: Path, h: str) -> None:
    target.with_name(target.name + ".hash").write_text(h)


QUALITY_CSV = ROOT.parent / "reports" / "data" / "references.csv"
QUALITY_HEADER = "case,family,dofs,front_h,far_h,coarse_dofs,coarse_front_h,own_l2,own_opening,own_probes"


def write_quality() -> None:
    """reports/data/references.csv: per case, the graded reference's size and own error (read
    by `xfem-cut report` and the tests; committed with the study's CSVs)."""
    rows = []
    for case, family in FAMILY.items():
        path = OUT / case / "manifest.json"
        if not path.exists():
            continue
        m = json.loads(path.read_text())
        fine, coarse, own = m.get(f"{family}_fine/p2"), m.get(f"{family}_fine_coarse/p2"), m.get("own_error")
        if not (fine and coarse and own and "mesh_sizes" in fine and "mesh_sizes" in coarse):
            continue
        num = lambda v: "nan" if v is None else repr(float(v))
        rows.append(",".join([case, family, str(fine["dofs"]), num(fine["mesh_sizes"]["singular_h_mean"]),
                              num(fine["mesh_sizes"]["h_far"]), str(coarse["dofs"]),
                              num(coarse["mesh_sizes"]["singular_h_mean"]), num(own["l2_rel"]),
                              num(own["opening_rel"]), num(own["probe_rel"])]))
    if rows:
        QUALITY_CSV.parent.mkdir(parents=True, exist_ok=True)
        QUALITY_CSV.write_text("\n".join([QUALITY_HEADER] + rows) + "\n")
        print(f"refs: {len(rows)} reference qualities in {QUALITY_CSV}", flush=True)


class Job:
    """One step of the pipeline: a command, the jobs it waits for, and how it may share the
    machine (`cmd`: a list, None, or a function giving either when the job starts). `alone`: nothing else runs beside it (timed solves: their times are compared with
    ours in the report; the scikit-fem P2 solves beyond L0: up to 19 GB). `then`: what the
    scheduler does in its own thread once the command succeeded (manifests, hashes)."""

    def __init__(self, name: str, cmd, after: list[str], then, alone: bool = False,
                 env: dict | None = None):
        self.name, self.cmd, self.after, self.then, self.alone, self.env = name, cmd, after, then, alone, env or {}


def schedule(jobs: list[Job], width: int) -> None:
    """Runs `jobs` (in list order where free to) `width` at a time, each after the jobs it
    names; a job marked `alone` runs with nothing beside it. Stops at the first failure."""
    import concurrent.futures as cf

    names = {j.name for j in jobs}
    done: set[str] = set()
    pending = list(jobs)
    running: dict = {}
    t_start = time.perf_counter()

    def start(pool, job: Job):
        def work():
            t0 = time.perf_counter()
            cmd = job.cmd() if callable(job.cmd) else job.cmd
            if cmd is None:
                return None, 0.0
            p = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env={**os.environ, **job.env})
            return p, time.perf_counter() - t0
        running[pool.submit(work)] = job

    with cf.ThreadPoolExecutor(max_workers=max(1, width)) as pool:
        while pending or running:
            exclusive = any(j.alone for j in running.values())
            for job in list(pending):
                if exclusive or len(running) >= max(1, width):
                    break
                if any(a in names and a not in done for a in job.after):
                    continue
                if job.alone and running:
                    break  # wait for the machine to empty; keep the order
                pending.remove(job)
                start(pool, job)
                exclusive = job.alone
            if not running:
                sys.exit(f"error: refs: jobs wait for each other: {[j.name for j in pending]}")
            finished, _ = cf.wait(list(running), return_when=cf.FIRST_COMPLETED)
            for f in finished:
                job = running.pop(f)
                p, wall = f.result()
                if p is not None and p.returncode != 0:
                    sys.stderr.write(p.stdout[-3000:] + p.stderr[-3000:])
                    for g in running:
                        g.cancel()
                    sys.exit(f"error: {job.name} failed (exit {p.returncode})")
                if p is not None:
                    elapsed = (time.perf_counter() - t_start) / 60
                    print(f"  done  {job.name} ({wall:.1f} s; {elapsed:.1f} min in)", flush=True)
                if job.then is not None:
                    job.then()
                done.add(job.name)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--set", choices=SETS, default="all")
    ap.add_argument("--np", type=int, default=1, help="MPI ranks for the FEniCSx solves")
    ap.add_argument("--jobs", type=int, default=1,
                    help="untimed jobs at once (meshes, graded references, scikit-fem); timed solves run alone")
    ap.add_argument("--cases", nargs="*", default=list(FAMILY))
    a = ap.parse_args()
    chosen = SETS[a.set]
    versions = tool_versions()
    # Untimed jobs share the cores: one BLAS thread each, so two of them use the two cores.
    shared_env = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"} if a.jobs > 1 else {}
    mesh_jobs = []
    for family in ["beam_crack", "beam_uncut", "slice_precut"]:
        for k in chosen["levels"]:
            mesh_jobs.append((family, f"L{k}", LEVELS[k], None))
        if family == "beam_uncut":
            continue
        if chosen["fine"]:
            mesh_jobs += [(family, name, h, front) for name, (h, front) in GRADED.items()]
        if chosen.get("uniform"):
            mesh_jobs.append((family, "uniform", UNIFORM_FINE, None))
    print(f"refs: {len(mesh_jobs)} meshes, set '{a.set}', {a.np} rank(s), {a.jobs} job(s) at once, tools {versions}",
          flush=True)
    jobs: list[Job] = []
    mesh_hash, mesh_job = {}, {}
    for family, name, h, front in mesh_jobs:
        target = OUT / "meshes" / family / f"{name}.msh"
        hh = file_hash(ROOT / "mesh.py", ROOT / "common.py", extra=f"{family} {h} {front} {versions}")
        mesh_hash[(family, name)] = hh
        if up_to_date(target, hh):
            print(f"  skip  mesh {family}/{name} (up to date)", flush=True)
            continue
        cmd = [PY, "mesh.py", family, str(h), str(target)] + ([] if front is None else ["--front", str(front)])
        what = f"mesh {family}/{name} h={h}" + ("" if front is None else f" front={front}")
        jobs.append(Job(what, cmd, [], lambda t=target, hh=hh: mark(t, hh), env=shared_env))
        mesh_job[(family, name)] = what

    # The manifest of each case is written only by the scheduler's thread, one job at a time.
    manifests: dict[str, dict] = {}
    timed: list[Job] = []
    for case in a.cases:
        family = FAMILY[case]
        # The graded references first: the study needs them, the levels only the tests.
        names = (list(GRADED) if chosen["fine"] else []) + (["uniform"] if chosen.get("uniform") else [])
        if chosen.get("solve_levels", True):
            names += [f"L{k}" for k in chosen["levels"]]
        manifest_path = OUT / case / "manifest.json"
        manifests[case] = json.loads(manifest_path.read_text()) if manifest_path.exists() else {}
        graded_jobs = []
        for name in names:
            msh = OUT / "meshes" / family / f"{name}.msh"
            for degree in ([1, 2] if name.startswith("L") else [2]):
                target = OUT / case / f"{family}_{name}" / f"p{degree}.vtu"
                hh = file_hash(ROOT / "solve_fenicsx.py", ROOT / "common.py", CASES / f"{case}.toml",
                               extra=f"{mesh_hash[(family, name)]} {degree} {versions} np={a.np}")
                key = f"{family}_{name}/p{degree}"
                if up_to_date(target, hh):
                    print(f"  skip  {case} {key} (up to date)", flush=True)
                    continue
                target.parent.mkdir(parents=True, exist_ok=True)
                cmd = [PY, "solve_fenicsx.py", case, str(msh), str(degree), str(target)]
                if name == "uniform":
                    cmd += ["--solver", "cg"]
                if a.np > 1:
                    cmd = ["mpirun", "--allow-run-as-root", "--oversubscribe", "-n", str(a.np)] + cmd

                def record(case=case, key=key, target=target, hh=hh, msh=msh, manifest_path=manifest_path):
                    info = json.loads(target.with_suffix(".json").read_text())
                    info["inputs_hash"] = hh
                    info["tools"] = versions
                    mesh_info = msh.with_suffix(".json")
                    if mesh_info.exists():
                        info["mesh_sizes"] = json.loads(mesh_info.read_text())
                    manifests[case][key] = info
                    write_json(manifest_path, manifests[case])
                    mark(target, hh)

                # The levels' solves are timed (the report sets our times beside them): alone.
                level = name.startswith("L")
                job = Job(f"FEniCSx {case} {key}", cmd, [mesh_job.get((family, name), "")], record, alone=level,
                          env={} if level else shared_env)
                (timed if level else jobs).append(job)
                if not level:
                    graded_jobs.append(job.name)
        for wanted, other, key in ((chosen["fine"], "fine_coarse", "own_error"),
                                   (chosen.get("uniform"), "uniform", "uniform_error")):
            if wanted:
                jobs.append(own_error_job(case, family, manifests, graded_jobs, other, key, shared_env))
    heavy: list[Job] = []
    for case, family, name, degree, steps, scale, ctol in COROT:
        if case not in a.cases or (family, name) not in mesh_hash or (name != "L0" and not chosen["fine"]):
            continue
        target = OUT / case / f"{family}_{name}" / f"corot_p{degree}.vtu"
        hh = file_hash(ROOT / "solve_corot.py", ROOT / "common.py", CASES / f"{case}.toml",
                       extra=f"{mesh_hash[(family, name)]} {degree} {steps} {scale} {ctol} {versions}")
        if up_to_date(target, hh):
            print(f"  skip  {case} {family}_{name}/corot_p{degree} (up to date)", flush=True)
            continue
        target.parent.mkdir(parents=True, exist_ok=True)
        cmd = [VENV_PY, "solve_corot.py", case, str(OUT / "meshes" / family / f"{name}.msh"), str(degree),
               str(target), "--steps", str(steps), "--scale", str(scale), "--tol", str(ctol)]
        big = degree == 2 and name != "L0"
        job = Job(f"scikit-fem corotational {case} {family}_{name}/p{degree} (load x{scale}, {steps} steps)", cmd,
                  [mesh_job.get((family, name), "")], lambda t=target, hh=hh: mark(t, hh), alone=big,
                  env={} if big else shared_env)
        (heavy if big else jobs).append(job)
    schedule(jobs + heavy + timed, a.jobs)
    write_quality()
    print("refs: done", flush=True)


def own_error_job(case: str, family: str, manifests: dict, after: list[str], other: str, key: str,
                  env: dict) -> Job:
    """The reference's own error: its difference from the 1.4x coarser graded reference,
    recorded in the manifest (cached by the hashes of both solutions). With other="uniform":
    the old uniform reference's error against the graded one. The command is decided when the
    job starts (the solutions' hashes exist only then)."""
    manifest_path = OUT / case / "manifest.json"
    fine = OUT / case / f"{family}_fine" / "p2.vtu"
    coarse = OUT / case / f"{family}_{other}" / "p2.vtu"
    target = OUT / case / f"{key}.json"
    state = {}

    def cmd():
        state["hash"] = file_hash(ROOT / "own_error.py", fine.with_name("p2.vtu.hash"), coarse.with_name("p2.vtu.hash"))
        if up_to_date(target, state["hash"]):
            return None
        return [PY, "own_error.py", case, str(fine), str(coarse), str(target)]

    def then():
        if not up_to_date(target, state["hash"]):
            mark(target, state["hash"])
        manifests[case][key] = json.loads(target.read_text())
        write_json(manifest_path, manifests[case])

    return Job(f"{key.replace('_', ' ')} of the {case} reference", cmd, after, then, env=env)


if __name__ == "__main__":
    main()
