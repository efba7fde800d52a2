//! Both cores: the element loops on two threads (rayon, element chunks with
//! their own buffers) and the factorisation on two (faer's Par) give what
//! one thread gives, to round-off.

use std::path::Path;
use xfem_cut::assembly::{equation_shapes, evaluate, Request, Rotations, Workspace};
use xfem_cut::dynamics::{DynamicOptions, Newmark};
use xfem_cut::model::Model;
use xfem_cut::scene::{Analysis, Scene};
use xfem_cut::solve::{Cholesky, Parallelism};

fn bend() -> (Model, DynamicOptions) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/bend_dynamic.toml");
    let scene = Scene::load(&path).unwrap();
    let (model, _) = scene.build(scene.mesh(0).unwrap()).unwrap();
    let Analysis::Dynamic { options, .. } = scene.analysis else {
        panic!("dynamic")
    };
    (model, options)
}

fn rel(a: &[f64], b: &[f64]) -> f64 {
    let d = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>();
    let n = a.iter().map(|x| x * x).sum::<f64>();
    (d / n).sqrt()
}

#[test]
fn two_threads_assemble_what_one_does() {
    let (model, _) = bend();
    // A bent state: rotations far from the identity.
    let d: Vec<f64> = (0..model.n_dofs())
        .map(|i| 0.01 * ((i as f64) * 0.37).sin())
        .collect();
    let run = |threads: usize, exact_tangent: bool| {
        let mut ws = Workspace::with_parallelism(&model, Parallelism::threads(threads));
        let mut rot = Rotations::identity(&model);
        let mut f = vec![0.0; model.n_dofs()];
        let mut k = vec![0.0; model.pattern.nnz()];
        let e = evaluate(
            &model,
            &d,
            &mut rot,
            &mut ws,
            Request {
                forces: Some(&mut f),
                tangent: Some(&mut k),
                update_rotations: true,
                exact_tangent,
            },
        );
        (e, f, k, rot)
    };
    for exact in [false, true] {
        let (e1, f1, k1, r1) = run(1, exact);
        for threads in [2, 3] {
            let (e2, f2, k2, r2) = run(threads, exact);
            assert!((e1 - e2).abs() <= 1e-14 * e1.abs(), "{threads}: {e1} {e2}");
            assert!(
                rel(&f1, &f2) < 1e-14,
                "{threads}: forces {:e}",
                rel(&f1, &f2)
            );
            assert!(
                rel(&k1, &k2) < 1e-14,
                "{threads}: tangent {:e}",
                rel(&k1, &k2)
            );
            assert!(r1.0 == r2.0, "{threads}: rotations differ");
        }
    }
}

#[test]
fn a_two_thread_newmark_run_follows_the_one_thread_run() {
    let (model, options) = bend();
    let start = |threads: usize| {
        let par = Parallelism::threads(threads);
        let chol =
            Cholesky::fill_reducing(&model.pattern, Some(&equation_shapes(&model)), par).unwrap();
        let mut nm = Newmark::new(&model, chol, options).unwrap();
        nm.set_parallelism(par);
        nm.initialise_acceleration().unwrap();
        nm
    };
    let (mut one, mut two) = (start(1), start(2));
    let mut worst: f64 = 0.0;
    for _ in 0..20 {
        let (a, b) = (one.step().unwrap(), two.step().unwrap());
        assert_eq!(a.iterations, b.iterations);
        worst = worst.max(rel(&one.state.d, &two.state.d));
    }
    println!("two threads vs one over 20 steps: max relative difference {worst:e}");
    assert!(worst < 1e-12, "{worst:e}");
}
