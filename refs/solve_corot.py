#!/usr/bin/env python3
"""Corotational static reference with scikit-fem (run with the venv's python, refs/.venv).

Static equilibrium of the corotated linear energy psi(F) = mu |S - I|^2 + lam/2 tr(S - I)^2,
F = R S (polar decomposition at every quadrature point; for P1 the gradient is constant per
element, so per element). Its first Piola stress P = 2 mu (F - R) + lam tr(R^T F - I) R is
exactly the seed's corotational force R K (R^T x - x0) (refs/README.md says why). Newton
with load steps on the Dirichlet values and gravity and the exact tangent dP/dF (the
derivative of the polar rotation included, so convergence is quadratic: 3-4 iterations per
step), until |r| <= tol |f|. Same quadrature as the Rust solver: 1 point (P1), the 4-point
degree-2 rule (P2). scikit-fem gives the mesh, the P1/P2 bases (DOF maps, shape-function
gradients, quadrature); the forces and the tangent are evaluated with numpy over all elements
and points at once.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import meshio
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.linalg import splu
from skfem import Basis, ElementTetP1, ElementTetP2, MeshTet

from common import EDGES, VTK_QUADRATIC_TETRA, VTK_TETRA, lame, load_case, write_json, write_vtu


def direct_solve(K, r):
    """x = K⁻¹ r by a sparse direct LU: MUMPS through petsc4py (Debian's, beside dolfinx:
    a P2 L1 tangent in seconds), else SuperLU (minutes for the same; what P2 L1 used to take)."""
    try:
        from petsc4py import PETSc
    except ImportError:
        return splu(K.tocsc(), permc_spec="MMD_AT_PLUS_A").solve(r)
    K = K.tocsr()
    A = PETSc.Mat().createAIJ(size=K.shape, csr=(K.indptr.astype(PETSc.IntType),
                                                 K.indices.astype(PETSc.IntType), K.data),
                              comm=PETSc.COMM_SELF)
    ksp = PETSc.KSP().create(PETSc.COMM_SELF)
    ksp.setOperators(A)
    ksp.setType("preonly")
    pc = ksp.getPC()
    pc.setType("lu")
    pc.setFactorSolverType("mumps")
    b = A.createVecLeft()
    b.setArray(r)
    x = A.createVecRight()
    ksp.solve(b, x)
    out = x.getArray().copy()
    for obj in (ksp, A, b, x):
        obj.destroy()
    return out


def polar(F: np.ndarray) -> np.ndarray:
    """Rotations of the polar decompositions of F[..., 3, 3] (det R = +1)."""
    U, _, Vt = np.linalg.svd(F)
    d = np.sign(np.linalg.det(U @ Vt))
    U[..., :, 2] *= d[..., None]
    return U @ Vt


class Corotated:
    """The corotated energy on a scalar scikit-fem basis; vector DOF 3 s + i is
    component i of scalar DOF s. Forces and tangents are evaluated for all
    elements and quadrature points at once (numpy), not per basis-function
    pair as a scikit-fem form would (that made P2 take ~5 s per iteration)."""

    def __init__(self, basis: Basis, lam: float, mu: float):
        self.lam, self.mu = lam, mu
        nb = basis.Nbfun
        self.dx = basis.dx  # weights x |det J|, (element, point)
        # Scalar shape-function gradients g[e, q, a, k] and values phi[e, q, a].
        self.g = np.stack([basis.basis[a][0].grad for a in range(nb)]).transpose(2, 3, 0, 1)
        self.phi = np.stack([basis.basis[a][0].value for a in range(nb)]).transpose(1, 2, 0)
        sdofs = basis.element_dofs.T  # (element, a)
        self.vdofs = (3 * sdofs[:, :, None] + np.arange(3)).reshape(len(sdofs), 3 * nb)
        self.n = 3 * basis.N
        rows = np.broadcast_to(self.vdofs[:, :, None], (len(sdofs), 3 * nb, 3 * nb))
        self.rows, self.cols = rows.ravel(), np.swapaxes(rows, 1, 2).ravel()

    def rotations(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ue = u[self.vdofs].reshape(len(self.vdofs), -1, 3)  # (element, a, i)
        F = np.eye(3) + np.einsum("eai,eqak->eqik", ue, self.g)
        return F, polar(F)

    def internal(self, u: np.ndarray) -> np.ndarray:
        F, R = self.rotations(u)
        RtF = np.einsum("eqki,eqkj->eqij", R, F)
        P = 2 * self.mu * (F - R) + self.lam * (np.einsum("eqii->eq", RtF) - 3)[..., None, None] * R
        fe = np.einsum("eq,eqik,eqak->eai", self.dx, P, self.g).reshape(len(self.vdofs), -1)
        return np.bincount(self.vdofs.ravel(), fe.ravel(), minlength=self.n)

    def body(self, rho_g: np.ndarray) -> np.ndarray:
        fe = np.einsum("eq,eqa,i->eai", self.dx, self.phi, rho_g).reshape(len(self.vdofs), -1)
        return np.bincount(self.vdofs.ravel(), fe.ravel(), minlength=self.n)

    def dP_dF(self, u: np.ndarray) -> np.ndarray:
        """The exact tangent A[e, q, i, k, j, l] = dP_ik / dF_jl of P = 2 mu (F - R) + lam (tr S - 3) R,
        S = R^T F, rotation included: dR = R W with W skew, W S + S W = R^T dF - dF^T R, i.e.
        (tr S I - S) w = axial(R^T dF - dF^T R) for W's axial vector w (tr(dR^T F) = 0)."""
        F, R = self.rotations(u)
        S = np.einsum("eqki,eqkj->eqij", R, F)
        trS = np.einsum("eqii->eq", S)
        lam, mu = self.lam, self.mu
        Z = trS[..., None, None] * np.eye(3) - S
        A = np.empty(F.shape[:2] + (3, 3, 3, 3))
        for j in range(3):
            for l in range(3):
                M = R[..., j, :, None] * np.eye(3)[l]  # R^T dF for dF = e_j e_l^T
                K = M - np.swapaxes(M, -1, -2)
                w = np.linalg.solve(Z, np.stack([K[..., 2, 1], K[..., 0, 2], K[..., 1, 0]], axis=-1)[..., None])[..., 0]
                W = np.zeros_like(M)
                W[..., 0, 1], W[..., 0, 2], W[..., 1, 2] = -w[..., 2], w[..., 1], -w[..., 0]
                W -= np.swapaxes(W, -1, -2)
                dR = R @ W
                dF = np.outer(np.eye(3)[j], np.eye(3)[l])
                A[..., :, :, j, l] = (2 * mu * (dF - dR) + lam * np.einsum("eqii->eq", M)[..., None, None] * R
                                      + lam * (trS - 3)[..., None, None] * dR)
        return A

    def tangent(self, u: np.ndarray):
        """Element stiffness sum_q dx g_a[k] A[i, k, j, l] g_b[l], assembled."""
        A = self.dP_dF(u)
        Ag = np.einsum("eqikjl,eqbl->eqikbj", A, self.g, optimize=True)
        K = np.einsum("eq,eqak,eqikbj->eaibj", self.dx, self.g, Ag, optimize=True)
        return coo_matrix((K.ravel(), (self.rows, self.cols)), shape=(self.n, self.n)).tocsc()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("case")
    ap.add_argument("mesh", type=Path)
    ap.add_argument("degree", type=int, choices=[1, 2])
    ap.add_argument("out", type=Path)
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--tol", type=float, default=1e-11)
    ap.add_argument("--scale", type=float, default=1.0,
                    help="factor on the Dirichlet values and gravity")
    ap.add_argument("--verbose", action="store_true")
    a = ap.parse_args()
    case = load_case(a.case)
    lam, mu, rho = lame(case)
    src = meshio.read(a.mesh)
    points, tets = src.points, src.cells_dict["tetra"]
    mesh = MeshTet(points.T.copy(), tets.T.copy())
    basis = Basis(mesh, ElementTetP1() if a.degree == 1 else ElementTetP2(), intorder=1 if a.degree == 1 else 2)
    energy = Corotated(basis, lam, mu)

    g = a.scale * np.array(case.get("gravity", {}).get("acceleration", [0.0, 0.0, 0.0]))
    f_body = energy.body(rho * g)
    # Dirichlet DOFs: nodes (and P2 edge mid-nodes) inside the closed boxes.
    lo, hi = points.min(axis=0), points.max(axis=0)
    tol = 1e-9 * np.linalg.norm(hi - lo)
    locs = [(basis.nodal_dofs[0], mesh.p)]
    if a.degree == 2:
        locs.append((basis.edge_dofs[0], 0.5 * (mesh.p[:, mesh.edges[0]] + mesh.p[:, mesh.edges[1]])))
    fixed = {}
    for fx in case["fix"]:
        bmin, bmax = np.array(fx["min"], float), np.array(fx["max"], float)
        disp = fx.get("displacement", [0.0, 0.0, 0.0])
        comps = [k for k, c in enumerate("xyz") if c in fx.get("components", "xyz")]
        for sdofs, x in locs:
            inside = np.all((x >= bmin[:, None] - tol) & (x <= bmax[:, None] + tol), axis=0)
            for k in comps:
                for s in sdofs[inside]:
                    fixed[3 * int(s) + k] = a.scale * disp[k]
    D = np.array(sorted(fixed), dtype=np.int64)
    vals = np.array([fixed[d] for d in D])
    free = np.setdiff1d(np.arange(energy.n), D)

    u = np.zeros(energy.n)
    t0 = time.perf_counter()
    iterations = []
    for step in range(1, a.steps + 1):
        s = step / a.steps
        u[D] = s * vals
        for it in range(200):
            r = s * f_body - energy.internal(u)
            scale = max(np.linalg.norm(s * f_body), np.linalg.norm(r + s * f_body), 1e-300)
            res = np.linalg.norm(r[free]) / scale
            # Intermediate load steps only need to stay close to the path.
            if res <= (a.tol if step == a.steps else 1e-6):
                break
            if a.verbose:
                print(f"step {step} it {it} residual {res:.3e}", flush=True)
            K = energy.tangent(u)
            du = np.zeros(energy.n)
            du[free] = direct_solve(K[free][:, free], r[free])
            # Backtracking on the residual norm (far from equilibrium Newton may overshoot).
            alpha = 1.0
            for _ in range(8):
                trial = u + alpha * du
                rt = s * f_body - energy.internal(trial)
                if np.linalg.norm(rt[free]) < np.linalg.norm(r[free]):
                    break
                alpha *= 0.5
            u = trial
        else:
            raise SystemExit(f"error: Newton did not converge in load step {step} (residual {res:.2e})")
        iterations.append(it)
    elapsed = time.perf_counter() - t0

    # Output on the original numbering (vertices, then edge mid-nodes), as p1/p2.vtu.
    U = u.reshape(-1, 3)
    u_vert = U[basis.nodal_dofs[0]]
    if a.degree == 1:
        write_vtu(a.out, points, tets, VTK_TETRA, u_vert)
    else:
        ed = basis.edge_dofs[0]
        edge_val = {(int(min(p, q)), int(max(p, q))): U[ed[i]] for i, (p, q) in enumerate(mesh.edges.T)}
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
    info = {"case": a.case, "mesh": str(a.mesh), "degree": a.degree, "dofs": int(energy.n), "load_steps": a.steps,
            "scale": a.scale, "tolerance": a.tol,
            "newton_iterations": iterations, "residual": float(res), "solve_s": elapsed}
    write_json(a.out.with_suffix(".json"), info)
    print(json.dumps(info))


if __name__ == "__main__":
    main()
