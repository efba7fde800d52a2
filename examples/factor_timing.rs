#![allow(clippy::needless_range_loop)]
use nalgebra::{Point3, Vector3};
use std::time::Instant;
use xfem_cut::assembly::{evaluate, Request, Rotations, Workspace};
use xfem_cut::material::Material;
use xfem_cut::mesh::box_mesh;
use xfem_cut::model::{Formulation, Model, ModelInput};
use xfem_cut::solve::Cholesky;
fn main() {
    let mesh = box_mesh(Point3::origin(), Point3::new(0.03, 0.06, 0.2), [6, 12, 24]);
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
