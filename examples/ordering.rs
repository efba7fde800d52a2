//! Fill-reducing orderings of the static stiffness: faer's AMD against METIS
//! nested dissection (on the node graph), the seed beam clamped at the bottom,
//! Tet4 and Tet10, with and without the half cut of `cases/bend.toml`.
//!
//! `cargo run --release --example ordering -- [max free DOFs] [max nnz(L) to factorise]`
//! Prints nnz(L), ordering + symbolic time, numeric factorisation and solve time.
use std::path::Path;
use std::time::Instant;
use xfem_cut::assembly::{equation_shapes, evaluate, Request, Rotations, Workspace};
use xfem_cut::model::Model;
use xfem_cut::scene::Scene;
use xfem_cut::solve::{Cholesky, Ordering, Parallelism};

/// The allocator the `xfem-cut` binary and the benches run with (see
/// `src/main.rs`), so that what this times is what a run pays.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn model(div: [usize; 3], element: &str, cut: bool) -> Model {
    let cut = if cut {
        "[[cut]]\norigin = [0.0, 0.0, 0.1]\nu = [0.015, 0.0, 0.0]\nv = [0.0, 0.06, 0.0]\n"
    } else {
        ""
    };
    let text = format!(
        "name = \"beam\"\n[body]\nbox = [[0.0, 0.0, 0.0], [0.03, 0.06, 0.2]]\nlevels = [[{}, {}, {}]]\nelement = \"{element}\"\n[material]\nyoung = 3.0e5\npoisson = 0.35\ndensity = 1070.0\n{cut}[[fix]]\nmin = [-inf, -inf, 0.0]\nmax = [inf, inf, 0.0]\n[gravity]\nacceleration = [9.81, 0.0, 0.0]\n[analysis]\ntype = \"static\"\n",
        div[0], div[1], div[2]
    );
    let scene = Scene::parse(&text, Path::new("beam.toml")).expect("scene");
    scene.build(scene.mesh(0).expect("mesh")).expect("model").0
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let max_dofs: usize = args
        .first()
        .map_or(120_000, |s| s.parse().expect("max DOFs"));
    let max_factor: usize = args
        .get(1)
        .map_or(150_000_000, |s| s.parse().expect("max nnz(L)"));
    let threads: usize = std::env::var("XFEM_THREADS").map_or(1, |s| s.parse().expect("threads"));
    let par = Parallelism::threads(threads);
    println!("threads {}; times in s; nnz in millions", par.n_threads());
    println!("element cut   free DOFs | ordering   nnz(L)  order+symb  numeric   solve");
    for element in ["tet4", "tet10"] {
        for a in [3usize, 5, 6, 7, 9, 10, 13, 16, 20] {
            let div = [a, 2 * a, (a as f64 * 20.0 / 3.0).round() as usize];
            // Nodes before building (a model past the limit is never built).
            let nodes = if element == "tet4" {
                (div[0] + 1) * (div[1] + 1) * (div[2] + 1)
            } else {
                (2 * div[0] + 1) * (2 * div[1] + 1) * (2 * div[2] + 1)
            };
            if 3 * nodes > max_dofs {
                continue;
            }
            for cut in [false, true] {
                if element == "tet10" && a == 6 {
                    continue;
                }
                let m = model(div, element, cut);
                let mut k = vec![0.0; m.pattern.nnz()];
                let mut rot = Rotations::identity(&m);
                let mut ws = Workspace::new(&m);
                let d = vec![0.0; m.n_dofs()];
                evaluate(
                    &m,
                    &d,
                    &mut rot,
                    &mut ws,
                    Request {
                        forces: None,
                        tangent: Some(&mut k),
                        update_rotations: false,
                        exact_tangent: false,
                    },
                );
                for nd in [false, true] {
                    let t = Instant::now();
                    let ordering = if nd {
                        Ordering::nested_dissection(&m.pattern, Some(&equation_shapes(&m)))
                            .expect("METIS")
                    } else {
                        Ordering::Amd
                    };
                    let mut chol = Cholesky::with(&m.pattern, &ordering, par).expect("symbolic");
                    let t_symbolic = t.elapsed().as_secs_f64();
                    let nnz = chol.factor_nnz();
                    let (mut t_numeric, mut t_solve) = (f64::NAN, f64::NAN);
                    if nnz <= max_factor {
                        let t = Instant::now();
                        chol.factorize(&k).expect("positive definite");
                        t_numeric = t.elapsed().as_secs_f64();
                        let mut b = vec![1.0; m.n_free];
                        let t = Instant::now();
                        chol.solve_in_place(&mut b);
                        t_solve = t.elapsed().as_secs_f64();
                    }
                    println!(
                        "{element:7} {:5} {:>9} | {:8} {:>8.2} {:>10.3} {:>8.3} {:>7.4}",
                        if cut { "yes" } else { "no" },
                        m.n_free,
                        if nd { "METIS-ND" } else { "AMD" },
                        nnz as f64 / 1e6,
                        t_symbolic,
                        t_numeric,
                        t_solve
                    );
                }
            }
        }
    }
}
