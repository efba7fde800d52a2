#!/usr/bin/env python3
"""Corotational static reference with scikit-fem (run with the venv's python, refs/.venv).

Static equilibrium of the corotated linear energy psi(F) = mu |S - I|^2 + lam/2 tr(S - I)^2,
F = R S (polar decomposition at every quadrature point; for P1 the gradient is constant per
element, so per element). Its first Piola stress P = 2 mu (F - R) + lam tr(R^T F - I) R is
exactly the seed's corotational force R K (R^T x - x0) (refs/README.md says why). Newton
with load steps on the Dirichlet values and gravity, tangent R K R^T (not the exact tangent,
so convergence is linear near the end), until |r| <= 1e-12 |f|. Same quadrature as the Rust
solver: 1 point (P1), the 4-point degree-2 rule (P2).
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import meshio
import numpy as np
from skfem import Basis, BilinearForm, ElementTetP1, ElementTetP2, ElementVector, LinearForm, MeshTet, asm, condense, solve
from skfem.helpers import ddot, grad

from common import EDGES, VTK_QUADRATIC_TETRA, VTK_TETRA, lame, load_case, write_json, write_vtu


def polar(F: np.ndarray) -> np.ndarray:
    """Rotation of the polar decomposition of F[i, j, ...] (det R = +1)."""
    Fm = np.moveaxis(F, (0, 1), (-2, -1))
    U, _, Vt = np.linalg.svd(Fm)
    d = np.sign(np.linalg.det(U @ Vt))
    U[..., :, 2] *= d[..., None]
    return np.moveaxis(U @ Vt, (-2, -1), (0, 1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("case")
    ap.add_argument("mesh", type=Path)
    ap.add_argument("degree", type=int, choices=[1, 2])
    ap.add_argument("out", type=Path)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--tol", type=float, default=1e-11)
    ap.add_argument("--scale", type=float, default=1.0,
                    help="factor on the Dirichlet values and gravity (a smaller load keeps P2 Newton short)")
    ap.add_argument("--verbose", action="store_true")
    a = ap.parse_args()
    case = load_case(a.case)
    lam, mu, rho = lame(case)
    src = meshio.read(a.mesh)
    points, tets = src.points, src.cells_dict["tetra"]
    mesh = MeshTet(points.T.copy(), tets.T.copy())
    elem = ElementVector(ElementTetP1() if a.degree == 1 else ElementTetP2())
    basis = Basis(mesh, elem, intorder=1 if a.degree == 1 else 2)
    eye = np.eye(3)[:, :, None, None]

    # The rotations are computed once per iteration and passed to the forms
    # (a form's kernel runs once per basis function pair).
    @LinearForm
    def internal(v, w):
        F = eye + grad(w["u"])
        R = w["R"]
        RtF = np.einsum("ki...,kj...->ij...", R, F)
        P = 2 * mu * (F - R) + lam * (np.einsum("ii...", RtF) - 3) * R
        return ddot(P, grad(v))

    @BilinearForm
    def tangent(u, v, w):
        R = w["R"]
        G = np.einsum("ki...,kj...->ij...", R, grad(u))  # R^T grad(u)
        eps = 0.5 * (G + np.einsum("ij...->ji...", G))
        sig = lam * np.einsum("ii...", eps) * np.eye(3)[:, :, None, None] + 2 * mu * eps
        return ddot(np.einsum("ik...,kj...->ij...", R, sig), grad(v))

    g = a.scale * np.array(case.get("gravity", {}).get("acceleration", [0.0, 0.0, 0.0]))

    @LinearForm
    def body(v, w):
        return rho * (g[0] * v[0] + g[1] * v[1] + g[2] * v[2])

    f_body = asm(body, basis)
    # Dirichlet DOFs: nodes (and P2 edge mid-nodes) inside the closed boxes.
    lo, hi = points.min(axis=0), points.max(axis=0)
    tol = 1e-9 * np.linalg.norm(hi - lo)
    locs = [(basis.nodal_dofs, mesh.p)]
    if a.degree == 2:
        locs.append((basis.edge_dofs, 0.5 * (mesh.p[:, mesh.edges[0]] + mesh.p[:, mesh.edges[1]])))
    fixed = {}
    for fx in case["fix"]:
        bmin, bmax = np.array(fx["min"], float), np.array(fx["max"], float)
        disp = fx.get("displacement", [0.0, 0.0, 0.0])
        comps = [k for k, c in enumerate("xyz") if c in fx.get("components", "xyz")]
        for dofs, x in locs:
            inside = np.all((x >= bmin[:, None] - tol) & (x <= bmax[:, None] + tol), axis=0)
            for k in comps:
                for d in dofs[k, inside]:
                    fixed[int(d)] = a.scale * disp[k]
    D = np.array(sorted(fixed), dtype=np.int64)
    vals = np.array([fixed[d] for d in D])

    u = np.zeros(basis.N)
    t0 = time.perf_counter()
    iterations = []
    for step in range(1, a.steps + 1):
        s = step / a.steps
        u[D] = s * vals
        for it in range(200):
            ui = basis.interpolate(u)
            R = polar(eye + ui.grad)
            r = s * f_body - asm(internal, basis, u=ui, R=R)
            free = np.setdiff1d(np.arange(basis.N), D)
            scale = max(np.linalg.norm(s * f_body), np.linalg.norm(r + s * f_body), 1e-300)
            res = np.linalg.norm(r[free]) / scale
            # Intermediate load steps only need to stay close to the path.
            if res <= (a.tol if step == a.steps else 1e-6):
                break
            if a.verbose:
                print(f"step {step} it {it} residual {res:.3e}", flush=True)
            K = asm(tangent, basis, R=R)
            du = solve(*condense(K, r, D=D, x=np.zeros(basis.N)))
            # Backtracking on the residual norm: R K R^T is not the exact tangent.
            alpha = 1.0
            for _ in range(8):
                trial = u + alpha * du
                ti = basis.interpolate(trial)
                rt = s * f_body - asm(internal, basis, u=ti, R=polar(eye + ti.grad))
                if np.linalg.norm(rt[free]) < np.linalg.norm(r[free]):
                    break
                alpha *= 0.5
            u = trial
        else:
            raise SystemExit(f"error: Newton did not converge in load step {step} (residual {res:.2e})")
        iterations.append(it)
    elapsed = time.perf_counter() - t0

    # Output on the original numbering (vertices, then edge mid-nodes), as p1/p2.vtu.
    nd = basis.nodal_dofs
    u_vert = u[nd].T
    if a.degree == 1:
        write_vtu(a.out, points, tets, VTK_TETRA, u_vert)
    else:
        ed = basis.edge_dofs
        edge_val = {(int(min(p, q)), int(max(p, q))): u[ed[:, i]] for i, (p, q) in enumerate(mesh.edges.T)}
        mid_index, mid_points, mid_vals = {}, [], []
        cells = np.zeros((len(tets), 10), dtype=np.int64)
        for e, t in enumerate(tets):
            cells[e, :4] = t
            for k, (p, q) in enumerate(EDGES):
                key = (int(min(t[p], t[q])), int(max(t[p], t[q])))
                if key not in mid_index:
                    mid_index[key] = len(points) + len(mid_points)
                    mid_points.append(0.5 * (points[t[p]] + points[t[q]]))
                    mid_vals.append(edge_val[key])
                cells[e, 4 + k] = mid_index[key]
        write_vtu(a.out, np.vstack([points, mid_points]), cells, VTK_QUADRATIC_TETRA, np.vstack([u_vert, mid_vals]))
    info = {"case": a.case, "mesh": str(a.mesh), "degree": a.degree, "dofs": int(basis.N), "load_steps": a.steps,
            "scale": a.scale, "tolerance": a.tol,
            "newton_iterations": iterations, "residual": float(res), "solve_s": elapsed}
    write_json(a.out.with_suffix(".json"), info)
    print(json.dumps(info))


if __name__ == "__main__":
    main()
