#![allow(clippy::needless_range_loop)]
//! Profiles corotational Newmark steps on the seed beam (1k tets): `perf record` target.
use nalgebra::{Point3, Vector3};
use std::time::Instant;
use xfem_cut::dynamics::{DynamicOptions, LinearSolver, Newmark};
use xfem_cut::material::Material;
use xfem_cut::mesh::box_mesh;
use xfem_cut::model::{Formulation, Model, ModelInput};
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
    let mesh = box_mesh(Point3::origin(), Point3::new(0.03, 0.06, 0.2), div);
    let fixed = mesh
        .nodes
        .iter()
        .enumerate()
        .filter(|(_, p)| p.z.abs() < 1e-12)
        .map(|(i, _)| (i, [Some(0.0); 3]))
        .collect();
    let m = Model::build(ModelInput {
        mesh,
        material: Material {
            young: 3e5,
            poisson: 0.35,
            density: 1070.0,
        },
        formulation: Formulation::Corotational,
        cut: None,
        fixed,
        gravity: Some(Vector3::new(9.81, 0.0, 0.0)),
        body_force: None,
        tractions: &[],
        need_mass: true,
    })
    .unwrap();
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
