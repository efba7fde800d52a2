#![allow(clippy::needless_range_loop)]
mod common;

use std::time::Instant;
use xfem_cut::assembly::{evaluate, Request, Rotations, Workspace};
use xfem_cut::solve::Cholesky;
fn main() {
    let m = common::clamped_beam([6, 12, 24]);
    let t = Instant::now();
    let mut chol = Cholesky::new(&m.pattern).unwrap();
    println!(
        "n {} nnz(A lower) {} nnz(L) {} symbolic {:?}",
        m.n_free,
        m.pattern.nnz(),
        chol.factor_nnz(),
        t.elapsed()
    );
    let mut k = vec![0.0; m.pattern.nnz()];
    let mut rot = Rotations::identity(&m);
    let mut ws = Workspace::new(&m);
    let d = vec![1e-3; m.n_dofs()];
    let mut f = vec![0.0; m.n_dofs()];
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
        println!("assembly {:?} numeric {:?} solve {:?}", ta, tf, t.elapsed());
    }
}
