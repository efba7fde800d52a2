//! The whole factor on one thread against the split factor on two
//! (`Cholesky::split`: nested dissection's first separator, the two halves
//! factorised side by side, the separator's Schur complement dense) on a
//! case and a gmsh mesh: ordering, symbolic and numeric factorisation (the
//! median of 5; the first touches fresh memory), solve, entries of the
//! factors, the separator's size and each solve's relative residual.
//!
//! `cargo run --release --example split_factor -- CASE.toml MESH.msh` (or a
//! level of the case's own meshes instead of MESH.msh)
use std::time::Instant;
use xfem_cut::assembly::{equation_shapes, evaluate, Request, Rotations, Workspace};
use xfem_cut::scene::Scene;
use xfem_cut::solve::{Cholesky, Ordering, Parallelism};

/// The allocator the `xfem-cut` binary and the benches run with (see
/// `src/main.rs`), so that what this times is what a run pays.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [case, mesh] = &args[..] else {
        eprintln!("usage: split_factor CASE.toml MESH.msh|LEVEL");
        std::process::exit(2);
    };
    let scene = Scene::load(std::path::Path::new(case)).expect("case");
    let mesh = match mesh.parse::<usize>() {
        Ok(level) => scene.mesh(level).expect("mesh"),
        Err(_) => {
            let mesh = scene.read_mesh(std::path::Path::new(mesh)).expect("mesh");
            if scene.element == xfem_cut::mesh::ElementKind::Tet10 {
                mesh.to_tet10()
            } else {
                mesh
            }
        }
    };
    let (m, _) = scene.build(mesh).expect("model");
    let blocks = equation_shapes(&m);
    let mut k = vec![0.0; m.pattern.nnz()];
    let mut f = vec![0.0; m.n_dofs()];
    evaluate(
        &m,
        &vec![0.0; m.n_dofs()],
        &mut Rotations::identity(&m),
        &mut Workspace::new(&m),
        Request {
            forces: Some(&mut f),
            tangent: Some(&mut k),
            update_rotations: false,
            exact_tangent: false,
        },
    );
    let b: Vec<f64> = (0..m.n_free).map(|i| (i as f64 * 0.37).sin()).collect();
    let residual = |x: &[f64]| {
        let mut y = vec![0.0; m.n_free];
        m.pattern.sym_mul_add(&k, x, &mut y);
        let r: f64 = y.iter().zip(&b).map(|(a, c)| (a - c).powi(2)).sum();
        (r / b.iter().map(|v| v * v).sum::<f64>()).sqrt()
    };
    let run = |name: &str, order: &dyn Fn() -> Cholesky| {
        let t = Instant::now();
        let mut chol = order();
        let t_analysis = ms(t);
        let mut numeric: Vec<f64> = (0..5)
            .map(|_| {
                let t = Instant::now();
                chol.factorize(&k).expect("positive definite");
                ms(t)
            })
            .collect();
        numeric.sort_by(f64::total_cmp);
        let mut x = b.clone();
        let t = Instant::now();
        chol.solve_in_place(&mut x);
        let rate = chol.factor_flops().map_or(String::new(), |f| {
            format!(
                ", {:.2} GFlop ({:.1} GFlop/s)",
                f * 1e-9,
                f * 1e-6 / numeric[2]
            )
        });
        println!(
            "{name}: ordering + symbolic {t_analysis:.1} ms, numeric {:.1} ms (median of 5{rate}), solve {:.1} ms, entries {}, residual {:.1e}",
            numeric[2],
            ms(t),
            chol.factor_nnz(),
            residual(&x)
        );
    };
    println!("{} free DOFs", m.n_free);
    run("whole, 1 thread", &|| {
        let nd = Ordering::nested_dissection(&m.pattern, Some(&blocks)).expect("ordering");
        Cholesky::with(&m.pattern, &nd, Parallelism::SEQUENTIAL).expect("symbolic")
    });
    let separated = Ordering::separated(&m.pattern, Some(&blocks))
        .expect("ordering")
        .expect("two sides");
    println!(
        "separator: {} equations, sides {} and {}",
        separated.separator.len(),
        separated.sides[0].len(),
        separated.sides[1].len()
    );
    run("split, 2 threads", &|| {
        let separated = Ordering::separated(&m.pattern, Some(&blocks)).expect("ordering");
        Cholesky::split(
            &m.pattern,
            &separated.expect("two sides"),
            Parallelism::threads(2),
        )
        .expect("symbolic")
    });
}
