//! What a static linear solve costs, part by part, on a case and a gmsh mesh
//! (`xfem-cut run CASE --mesh MESH` does the same work): the model (element
//! data, pattern and scatter maps), the fill-reducing ordering and symbolic
//! factorisation, the assembly of K, the numeric factorisation and the
//! solve; nnz(L). Threads from `XFEM_THREADS` (default 1).
//!
//! `cargo run --release --example static_profile -- CASE.toml MESH.msh`
use std::time::Instant;
use xfem_cut::assembly::{equation_shapes, evaluate, Request, Rotations, Workspace};
use xfem_cut::scene::Scene;
use xfem_cut::solve::{Cholesky, Parallelism};

/// The allocator the `xfem-cut` binary and the benches run with (see
/// `src/main.rs`), so that what this times is what a run pays.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [case, mesh] = &args[..] else {
        eprintln!("usage: static_profile CASE.toml MESH.msh");
        std::process::exit(2);
    };
    let threads: usize = std::env::var("XFEM_THREADS").map_or(1, |s| s.parse().expect("threads"));
    let par = Parallelism::threads(threads);
    let scene = Scene::load(std::path::Path::new(case)).expect("case");
    let mut mesh = scene.read_mesh(std::path::Path::new(mesh)).expect("mesh");
    if scene.element == xfem_cut::mesh::ElementKind::Tet10 {
        mesh = mesh.to_tet10();
    }
    let t = Instant::now();
    let (m, _) = scene.build(mesh).expect("model");
    let t_model = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let mut chol = Cholesky::fill_reducing(&m.pattern, Some(&equation_shapes(&m)), par).unwrap();
    let t_symbolic = t.elapsed().as_secs_f64();
    let mut k = vec![0.0; m.pattern.nnz()];
    let mut f = vec![0.0; m.n_dofs()];
    let mut rot = Rotations::identity(&m);
    let mut ws = Workspace::with_parallelism(&m, par);
    let d = vec![0.0; m.n_dofs()];
    let t = Instant::now();
    evaluate(
        &m,
        &d,
        &mut rot,
        &mut ws,
        Request {
            forces: Some(&mut f),
            tangent: Some(&mut k),
            update_rotations: false,
            exact_tangent: false,
        },
    );
    let t_assembly = t.elapsed().as_secs_f64();
    let t = Instant::now();
    chol.factorize(&k).unwrap();
    let t_numeric = t.elapsed().as_secs_f64();
    let mut b = vec![1.0; m.n_free];
    let t = Instant::now();
    chol.solve_in_place(&mut b);
    let t_solve = t.elapsed().as_secs_f64();
    println!(
        "{} free DOFs, nnz(K lower) {}, nnz(L) {}, {threads} thread(s): model {:.1} ms, symbolic {:.1} ms, assembly {:.1} ms, numeric {:.1} ms, solve {:.1} ms",
        m.n_free,
        m.pattern.nnz(),
        chol.factor_nnz(),
        t_model * 1e3,
        t_symbolic * 1e3,
        t_assembly * 1e3,
        t_numeric * 1e3,
        t_solve * 1e3
    );
}
