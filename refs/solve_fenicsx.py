#!/usr/bin/python3
"""Linear static solve of a case on a pre-cut gmsh mesh with FEniCSx (dolfinx 0.5.2), P1 or P2.

Reads material, [[fix]] boxes and [gravity] from the case file, so the reference and the
Rust solver solve the same problem. Assembly and MUMPS solve are timed separately, with the
forms compiled beforehand (JIT excluded). Writes the solution as VTU on the original mesh
numbering (see refs/README.md) and a JSON with DOFs, times and the true residual.
Runs under mpirun: the solution is gathered to rank 0 through topology, never coordinates.
"""
from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path

import meshio
import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from mpi4py import MPI
from petsc4py import PETSc

from common import EDGES, VTK_QUADRATIC_TETRA, VTK_TETRA, lame, load_case, write_json, write_vtu


def blas_name() -> str:
    try:
        for line in open("/proc/self/maps"):
            if "openblas" in line:
                return "openblas"
        return "reference or other (no libopenblas mapped)"
    except OSError:
        return "unknown"


def rigid_body_modes(V) -> PETSc.NullSpace:
    """The six rigid-body modes as the near null space of GAMG (translations, rotations)."""
    x = V.tabulate_dof_coordinates()
    modes = [fem.Function(V) for _ in range(6)]
    for m in modes:
        m.x.array[:] = 0.0
    a = [m.x.array.reshape(-1, 3) for m in modes]
    for k in range(3):
        a[k][:, k] = 1.0
    a[3][:, 0], a[3][:, 1] = -x[:, 1], x[:, 0]
    a[4][:, 0], a[4][:, 2] = x[:, 2], -x[:, 0]
    a[5][:, 1], a[5][:, 2] = -x[:, 2], x[:, 1]
    vecs = [m.vector for m in modes]
    from dolfinx import la
    la.orthonormalize(vecs)
    return PETSc.NullSpace().create(vectors=vecs)


def solve(case_name: str, msh_path: Path, degree: int, out: Path, solver: str = "mumps") -> dict:
    comm = MPI.COMM_WORLD
    case = load_case(case_name)
    lam, mu, rho = lame(case)
    src = meshio.read(msh_path)
    points, tets = src.points, src.cells_dict["tetra"].astype(np.int64)
    domain = ufl.Mesh(ufl.VectorElement("Lagrange", ufl.tetrahedron, 1))
    if comm.rank == 0:
        msh = dmesh.create_mesh(comm, tets, points, domain)
    else:
        msh = dmesh.create_mesh(comm, np.empty((0, 4), dtype=np.int64), np.empty((0, 3)), domain)
    V = fem.VectorFunctionSpace(msh, ("Lagrange", degree))

    lo, hi = points.min(axis=0), points.max(axis=0)
    tol = 1e-9 * np.linalg.norm(hi - lo)
    bcs = []
    for fx in case["fix"]:
        bmin, bmax = np.array(fx["min"], float), np.array(fx["max"], float)
        disp = fx.get("displacement", [0.0, 0.0, 0.0])
        comps = [k for k, c in enumerate("xyz") if c in fx.get("components", "xyz")]
        marker = lambda x, bmin=bmin, bmax=bmax: np.all((x >= bmin[:, None] - tol) & (x <= bmax[:, None] + tol), axis=0)
        for k in comps:
            Vk, _ = V.sub(k).collapse()
            dofs = fem.locate_dofs_geometrical((V.sub(k), Vk), marker)[0]
            bcs.append(fem.dirichletbc(PETSc.ScalarType(disp[k]), dofs, V.sub(k)))

    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    eps = lambda w: ufl.sym(ufl.grad(w))
    sigma = lambda w: lam * ufl.tr(eps(w)) * ufl.Identity(3) + 2 * mu * eps(w)
    g = case.get("gravity", {}).get("acceleration", [0.0, 0.0, 0.0])
    f = fem.Constant(msh, PETSc.ScalarType(tuple(rho * np.array(g))))
    a_form = fem.form(ufl.inner(sigma(u), eps(v)) * ufl.dx)  # JIT here, not timed
    L_form = fem.form(ufl.dot(f, v) * ufl.dx)

    comm.barrier()
    t0 = time.perf_counter()
    A = fem.petsc.assemble_matrix(a_form, bcs=bcs)
    A.assemble()
    b = fem.petsc.assemble_vector(L_form)
    fem.petsc.apply_lifting(b, [a_form], bcs=[bcs])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    fem.petsc.set_bc(b, bcs)
    comm.barrier()
    t_assembly = time.perf_counter() - t0

    ksp = PETSc.KSP().create(comm)
    ksp.setOperators(A)
    if solver == "mumps":
        ksp.setType("preonly")
        ksp.getPC().setType("lu")
        ksp.getPC().setFactorSolverType("mumps")
    else:
        # CG + smoothed aggregation with the rigid-body modes: little memory, for the big meshes.
        A.setNearNullSpace(rigid_body_modes(V))
        ksp.setType("cg")
        ksp.getPC().setType("gamg")
        ksp.setTolerances(rtol=1e-13, atol=0.0, max_it=5000)
        opts = PETSc.Options()
        opts["mg_levels_ksp_type"] = "chebyshev"
        opts["mg_levels_pc_type"] = "jacobi"
        ksp.setFromOptions()
    uh = fem.Function(V)
    t0 = time.perf_counter()
    ksp.solve(b, uh.vector)
    comm.barrier()
    t_solve = time.perf_counter() - t0
    ksp_its = ksp.getIterationNumber()
    uh.x.scatter_forward()
    r = b.duplicate()
    A.mult(uh.vector, r)
    r.axpy(-1.0, b)
    residual = r.norm() / max(b.norm(), 1e-300)
    ndofs = V.dofmap.index_map.size_global * V.dofmap.index_map_bs

    # Values by original vertex and by original edge (vertex pair), from each local cell.
    x_dofs = V.tabulate_dof_coordinates()
    geo = msh.geometry
    orig = geo.input_global_indices
    vals = uh.x.array.reshape(-1, 3)
    vertex_val, edge_val = {}, {}
    n_local = msh.topology.index_map(3).size_local
    for c in range(n_local):
        gnodes = geo.dofmap.links(c)
        gx = geo.x[gnodes]
        ids = [int(orig[n]) for n in gnodes]
        cdofs = V.dofmap.cell_dofs(c)
        for dof in cdofs:
            x = x_dofs[dof]
            d = np.linalg.norm(gx - x, axis=1)
            i = int(np.argmin(d))
            if d[i] < 1e-12 * (1 + np.abs(x).max()):
                vertex_val[ids[i]] = vals[dof]
                continue
            for (p, q) in [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]:
                if np.linalg.norm(0.5 * (gx[p] + gx[q]) - x) < 1e-12 * (1 + np.abs(x).max()):
                    edge_val[(min(ids[p], ids[q]), max(ids[p], ids[q]))] = vals[dof]
                    break
            else:
                raise RuntimeError(f"dof {dof} of cell {c} matches no vertex or edge midpoint")
    gathered = comm.gather((vertex_val, edge_val), root=0)
    for obj in (ksp, A, b, r):
        obj.destroy()
    info = {"case": case_name, "mesh": str(msh_path), "degree": degree, "dofs": int(ndofs), "ranks": comm.size,
            "solver": solver if solver == "mumps" else f"cg+gamg ({ksp_its} iterations)",
            "assembly_s": t_assembly, "solve_s": t_solve, "residual": residual, "blas": blas_name(),
            "tets": int(len(tets)), "nodes": int(len(points)),
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}
    if comm.rank != 0:
        return info
    vertex_val, edge_val = {}, {}
    for vv, ee in gathered:
        vertex_val.update(vv)
        edge_val.update(ee)
    u_vert = np.array([vertex_val[i] for i in range(len(points))])
    if degree == 1:
        write_vtu(out, points, tets, VTK_TETRA, u_vert)
    else:
        mid_index, mid_points, mid_vals = {}, [], []
        cells = np.zeros((len(tets), 10), dtype=np.int64)
        for e, t in enumerate(tets):
            cells[e, :4] = t
            for k, (p, q) in enumerate(EDGES):
                key = (min(t[p], t[q]), max(t[p], t[q]))
                if key not in mid_index:
                    mid_index[key] = len(points) + len(mid_points)
                    mid_points.append(0.5 * (points[t[p]] + points[t[q]]))
                    mid_vals.append(edge_val[key])
                cells[e, 4 + k] = mid_index[key]
        write_vtu(out, np.vstack([points, mid_points]), cells, VTK_QUADRATIC_TETRA, np.vstack([u_vert, mid_vals]))
    return info


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("case")
    ap.add_argument("mesh", type=Path)
    ap.add_argument("degree", type=int, choices=[1, 2])
    ap.add_argument("out", type=Path, help="output .vtu; timings go beside it as .json")
    ap.add_argument("--solver", choices=["mumps", "cg"], default="mumps")
    a = ap.parse_args()
    info = solve(a.case, a.mesh, a.degree, a.out, a.solver)
    if MPI.COMM_WORLD.rank == 0:
        write_json(a.out.with_suffix(".json"), info)
        print(json.dumps(info))


if __name__ == "__main__":
    main()
