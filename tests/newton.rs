//! Newton iterations per step of the shipped corotational dynamic scenes,
//! pinned: the exact tangent (c₀M + c₁D + K_exact) against R K Rᵀ.

use std::path::Path;
use xfem_cut::dynamics::{DynamicOptions, Newmark};
use xfem_cut::scene::{Analysis, Scene};
use xfem_cut::solve::Cholesky;

/// Newton iterations of each of `steps` steps of a shipped case at level 0
/// (AMD ordering, one thread: deterministic), with `edit` applied to the case text.
fn iterations(file: &str, edit: (&str, &str), exact_tangent: bool, steps: usize) -> Vec<usize> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("cases")
        .join(file);
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace(edit.0, edit.1);
    let scene = Scene::parse(&text, &path).unwrap();
    let (model, _) = scene.build(scene.mesh(0).unwrap()).unwrap();
    let Analysis::Dynamic { options, .. } = scene.analysis else {
        panic!("{file} is dynamic")
    };
    let options = DynamicOptions {
        exact_tangent,
        ..options
    };
    let mut nm = Newmark::new(&model, Cholesky::new(&model.pattern).unwrap(), options).unwrap();
    nm.initialise_acceleration().unwrap();
    (0..steps)
        .map(|_| {
            let r = nm.step().unwrap();
            assert!(r.residual <= options.tolerance);
            assert_eq!(r.factorisations, r.iterations);
            assert_eq!(r.fallbacks, 0);
            r.iterations
        })
        .collect()
}

/// Run-length form [(count, iterations)] of a per-step list, to pin it readably.
fn runs(v: &[usize]) -> Vec<(usize, usize)> {
    let mut out: Vec<(usize, usize)> = Vec::new();
    for &x in v {
        match out.last_mut() {
            Some((n, y)) if *y == x => *n += 1,
            _ => out.push((1, x)),
        }
    }
    out
}

#[test]
fn bend_dynamic_newton_iterations_are_pinned() {
    for file in ["bend_dynamic.toml", "bend_dynamic_uncut.toml"] {
        let exact = iterations(file, ("", ""), true, 60);
        let corotated = iterations(file, ("", ""), false, 60);
        let (se, sc): (usize, usize) = (exact.iter().sum(), corotated.iter().sum());
        println!("{file}: exact {se} {:?}", runs(&exact));
        println!("{file}: R K Rᵀ {sc} {:?}", runs(&corotated));
        // 60 steps: the 0.5 s ramp and 0.1 s after it.
        let (want_exact, want_corotated) = match file {
            "bend_dynamic.toml" => (255, 303),
            _ => (254, 303),
        };
        assert_eq!((se, sc), (want_exact, want_corotated), "{file}");
        assert!(*exact.iter().max().unwrap() <= 5, "{file}: {exact:?}");
    }
}

/// Without stiffness-proportional damping the exact tangent is the whole
/// Newton matrix, and Newton converges quadratically: three iterations a
/// step (the residual goes ~1 → 1e-2 → 1e-5 → 1e-12), against six or seven on R K Rᵀ.
#[test]
fn without_stiffness_damping_newton_on_the_exact_tangent_is_quadratic() {
    let edit = ("stiffness = 0.01", "stiffness = 0.0");
    let exact = iterations("bend_dynamic.toml", edit, true, 60);
    let corotated = iterations("bend_dynamic.toml", edit, false, 60);
    println!("exact {:?}", runs(&exact));
    println!("R K Rᵀ {:?}", runs(&corotated));
    assert!(exact.iter().all(|&i| i <= 3), "{exact:?}");
    let (se, sc): (usize, usize) = (exact.iter().sum(), corotated.iter().sum());
    assert!(2 * se < sc, "exact {se}, R K Rᵀ {sc}");
}

/// The step that reuses one factorisation (CG preconditioned by the warped
/// factor, refactorising only when CG needs more than 25 iterations) follows
/// the refactorising Newton step: 100 steps of bend_dynamic at level 0.
#[test]
fn the_warped_pcg_step_follows_the_refactorising_step() {
    use xfem_cut::dynamics::LinearSolver;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/bend_dynamic.toml");
    let scene = Scene::load(&path).unwrap();
    let (model, _) = scene.build(scene.mesh(0).unwrap()).unwrap();
    let Analysis::Dynamic { options, .. } = scene.analysis else {
        panic!("dynamic")
    };
    let start = |linear_solver| {
        let o = DynamicOptions {
            linear_solver,
            ..options
        };
        let mut nm = Newmark::new(&model, Cholesky::new(&model.pattern).unwrap(), o).unwrap();
        nm.initialise_acceleration().unwrap();
        nm
    };
    let mut direct = start(LinearSolver::Direct);
    let mut fast = start(LinearSolver::WarpedPcg {
        tolerance: 1e-10,
        max_cg: 25,
    });
    let (mut worst, mut factorisations, mut cg) = (0.0f64, 0, 0);
    for _ in 0..100 {
        direct.step().unwrap();
        let r = fast.step().unwrap();
        factorisations += r.factorisations;
        cg += r.cg_iterations;
        let norm = direct.state.d.iter().map(|x| x * x).sum::<f64>().sqrt();
        let diff = (direct.state.d.iter())
            .zip(&fast.state.d)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            .sqrt();
        worst = worst.max(diff / norm);
    }
    println!(
        "warped PCG: {factorisations} factorisations, {cg} CG iterations in 100 steps (direct: {}); max relative difference {worst:e}",
        direct.factorisations()
    );
    assert!(worst < 1e-9, "{worst:e}");
    assert!(factorisations <= 5, "{factorisations}");
}
