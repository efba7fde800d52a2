//! The discrete energy balance of a dynamic scene's Newmark steps, level 0:
//! per step t, E = ½vᵀMv + W, ΔE, the trapezoid error of the internal work
//! over the free DOFs, ½(fₙ + fₙ₊₁)·Δd − ΔW (zero for linear forces, O(Δd³)
//! for corotational ones), and the kinetic energy.
//!
//! `cargo run --release --example energy_balance -- cases/bend_dynamic.toml`
use std::path::Path;
use xfem_cut::assembly::{equation_shapes, evaluate, Request, Rotations, Workspace};
use xfem_cut::dynamics::Newmark;
use xfem_cut::scene::{Analysis, Scene};
use xfem_cut::solve::{Cholesky, Parallelism};

fn main() {
    let path = std::env::args().nth(1).expect("case");
    let text = std::fs::read_to_string(&path).unwrap();
    let scene = Scene::parse(&text, Path::new(&path)).unwrap();
    let (model, _) = scene.build(scene.mesh(0).unwrap()).unwrap();
    let Analysis::Dynamic { options, .. } = scene.analysis else {
        panic!()
    };
    let chol = Cholesky::fill_reducing(
        &model.pattern,
        Some(&equation_shapes(&model)),
        Parallelism::SEQUENTIAL,
    )
    .unwrap();
    let mut nm = Newmark::new(&model, chol, options).unwrap();
    nm.initialise_acceleration().unwrap();
    let mut ws = Workspace::new(&model);
    let n = model.n_dofs();
    let forces = |d: &[f64], ws: &mut Workspace| {
        let mut f = vec![0.0; n];
        let mut rot = Rotations::identity(&model);
        let w = evaluate(
            &model,
            d,
            &mut rot,
            ws,
            Request {
                forces: Some(&mut f),
                tangent: None,
                update_rotations: model.formulation == xfem_cut::model::Formulation::Corotational,
                exact_tangent: false,
            },
        );
        (f, w)
    };
    let mut d0 = nm.state.d.clone();
    let (mut f0, _) = forces(&d0, &mut ws);
    let mut e0 = nm.energies();
    for _ in 0..options.steps {
        nm.step().unwrap();
        let d1 = nm.state.d.clone();
        let (f1, _) = forces(&d1, &mut ws);
        let e1 = nm.energies();
        let mut trap = 0.0;
        for i in (0..n).filter(|&i| model.equation[i] != xfem_cut::model::NONE) {
            trap += 0.5 * (f0[i] + f1[i]) * (d1[i] - d0[i]);
        }
        let err = trap - (e1.strain - e0.strain);
        let de = e1.kinetic + e1.strain - e0.kinetic - e0.strain;
        println!(
            "{:.4} E {:.9e} dE {:+.3e} trap_err {:+.3e} K {:.3e}",
            nm.state.time,
            e1.kinetic + e1.strain,
            de,
            err,
            e1.kinetic
        );
        d0 = d1;
        f0 = f1;
        e0 = e1;
    }
}
