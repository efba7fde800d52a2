#![allow(clippy::needless_range_loop)]
//! Profiles corotational Newmark steps on the seed beam (1k tets): `perf record` target.
mod common;

use std::time::Instant;
use xfem_cut::dynamics::{DynamicOptions, LinearSolver, Newmark};
use xfem_cut::solve::Cholesky;
fn main() {
    let div: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().unwrap())
        .collect();
    let div = if div.len() == 3 {
        [div[0], div[1], div[2]]
    } else {
        [3, 6, 10]
    };
    let m = common::clamped_beam(div);
    let chol = Cholesky::new(&m.pattern).unwrap();
    // XFEM_PCG=<max CG iterations> uses CG preconditioned by the last factorisation.
    let linear_solver = match std::env::var("XFEM_PCG").ok().and_then(|s| s.parse().ok()) {
        Some(max_cg) => LinearSolver::Pcg {
            tolerance: 1e-8,
            max_cg,
        },
        None => LinearSolver::Direct,
    };
    let opts = DynamicOptions {
        dt: 0.01,
        steps: 1,
        max_iterations: 1,
        linear_solver,
        ..DynamicOptions::default()
    };
    let mut nm = Newmark::new(&m, chol, opts).unwrap();
    let t = Instant::now();
    let n = 200;
    for _ in 0..n {
        nm.step().unwrap();
    }
    println!(
        "{} tets: {:.3} ms/step, {} factorisations, {} CG iterations in {n} steps",
        m.mesh.n_elements(),
        t.elapsed().as_secs_f64() * 1e3 / n as f64,
        nm.factorisations(),
        nm.cg_iterations()
    );
}
