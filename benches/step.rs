#![allow(clippy::needless_range_loop)]
//! Criterion benches: precompute and one time step, linear and corotational, Tet4 and Tet10.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use std::hint::black_box;
use xfem_cut::assembly::{evaluate, Request, Rotations, Workspace};
use xfem_cut::dynamics::{DynamicOptions, LinearSolver, Newmark};
use xfem_cut::mesh::TetMesh;
use xfem_cut::model::{Formulation, Model};
use xfem_cut::solve::Cholesky;
use xfem_cut::study::fixtures::{beam_mesh, seed_beam};

/// The seed's beam, bottom clamped, gravity in +x, with mass.
fn model(mesh: TetMesh, formulation: Formulation) -> Model {
    seed_beam(mesh, formulation, None).unwrap()
}

fn chol_new(m: &Model) -> Cholesky {
    Cholesky::new(&m.pattern).unwrap()
}

fn benches(c: &mut Criterion) {
    let sizes = [
        ("1k", [3, 6, 10], false),
        ("10k", [6, 12, 24], false),
        ("1k", [3, 6, 10], true),
    ];
    let mut g = c.benchmark_group("precompute");
    g.sample_size(10);
    for (label, div, tet10) in sizes {
        let kind = if tet10 { "tet10" } else { "tet4" };
        g.bench_function(
            BenchmarkId::new(format!("model+symbolic/{kind}"), label),
            |b| {
                b.iter(|| {
                    let m = model(beam_mesh(div, tet10), Formulation::Corotational);
                    let chol = Cholesky::new(&m.pattern).unwrap();
                    black_box((m.n_free, chol.factor_nnz()))
                })
            },
        );
    }
    g.finish();

    let mut g = c.benchmark_group("step");
    g.sample_size(10);
    for (label, div, tet10) in sizes {
        let kind = if tet10 { "tet10" } else { "tet4" };
        for formulation in [Formulation::Linear, Formulation::Corotational] {
            let m = model(beam_mesh(div, tet10), formulation);
            let name = format!(
                "{}/{kind}/{}tets",
                if formulation == Formulation::Linear {
                    "linear"
                } else {
                    "corotational"
                },
                m.mesh.n_elements()
            );
            let solvers: &[(&str, LinearSolver)] = if formulation == Formulation::Linear {
                &[("", LinearSolver::Direct)]
            } else {
                &[
                    ("/direct", LinearSolver::Direct),
                    (
                        "/pcg",
                        LinearSolver::Pcg {
                            tolerance: 1e-8,
                            max_cg: 25,
                        },
                    ),
                ]
            };
            for (solver_name, solver) in solvers {
                let opts = DynamicOptions {
                    dt: 0.01,
                    steps: 1,
                    max_iterations: 1,
                    linear_solver: *solver,
                    ..DynamicOptions::default()
                };
                let mut nm = Newmark::new(&m, chol_new(&m), opts).unwrap();
                nm.step().unwrap();
                g.bench_function(
                    BenchmarkId::new(format!("{name}{solver_name}"), label),
                    |b| b.iter(|| black_box(nm.step().unwrap())),
                );
            }
        }
        // The assembly alone (rotations + forces + tangent) for the corotational step.
        let m = model(beam_mesh(div, tet10), Formulation::Corotational);
        let d = vec![1e-3; m.n_dofs()];
        let mut rot = Rotations::identity(&m);
        let mut ws = Workspace::new(&m);
        let mut f = vec![0.0; m.n_dofs()];
        let mut k = vec![0.0; m.pattern.nnz()];
        g.bench_function(
            BenchmarkId::new(
                format!("corotational-assembly/{kind}/{}tets", m.mesh.n_elements()),
                label,
            ),
            |b| {
                b.iter(|| {
                    black_box(evaluate(
                        &m,
                        &d,
                        &mut rot,
                        &mut ws,
                        Request {
                            forces: Some(&mut f),
                            tangent: Some(&mut k),
                            update_rotations: true,
                            exact_tangent: false,
                        },
                    ))
                })
            },
        );
    }
    g.finish();
}

criterion_group!(step, benches);
criterion_main!(step);
