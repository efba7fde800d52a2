#![allow(clippy::needless_range_loop)]
//! What a corotational Newton iteration costs, part by part, on the 10k-tet
//! clamped beam: assembly (rotations + forces + tangent), numeric
//! factorisation and solve, with AMD and with the fill-reducing rule
//! (`Cholesky::fill_reducing`), at `XFEM_THREADS` threads (default 1).
mod common;

use std::time::Instant;
use xfem_cut::assembly::{equation_shapes, evaluate, Request, Rotations, Workspace};
use xfem_cut::solve::{Cholesky, Parallelism};

/// The allocator the `xfem-cut` binary and the benches run with (see
/// `src/main.rs`), so that what this times is what a run pays.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    let m = common::clamped_beam([6, 12, 24]);
    let threads: usize = std::env::var("XFEM_THREADS").map_or(1, |s| s.parse().expect("threads"));
    let par = Parallelism::threads(threads);
    let mut k = vec![0.0; m.pattern.nnz()];
    let mut rot = Rotations::identity(&m);
    let mut ws = Workspace::new(&m);
    let d = vec![1e-3; m.n_dofs()];
    let mut f = vec![0.0; m.n_dofs()];
    for rule in [false, true] {
        let t = Instant::now();
        let mut chol = if rule {
            Cholesky::fill_reducing(&m.pattern, Some(&equation_shapes(&m)), par).unwrap()
        } else {
            Cholesky::with(&m.pattern, &Default::default(), par).unwrap()
        };
        println!(
            "{}: n {} nnz(A lower) {} nnz(L) {} symbolic {:?}, {} threads",
            if rule { "fill_reducing" } else { "AMD" },
            m.n_free,
            m.pattern.nnz(),
            chol.factor_nnz(),
            t.elapsed(),
            par.n_threads()
        );
        for _ in 0..3 {
            let t = Instant::now();
            evaluate(
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
            );
            let ta = t.elapsed();
            let t = Instant::now();
            chol.factorize(&k).unwrap();
            let tf = t.elapsed();
            let mut b = vec![1.0; m.n_free];
            let t = Instant::now();
            chol.solve_in_place(&mut b);
            println!(
                "  assembly {:?} numeric {:?} solve {:?}",
                ta,
                tf,
                t.elapsed()
            );
        }
    }
}
