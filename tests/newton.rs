//! Newton in dynamics: the step's Newton matrix is the derivative of its
//! residual (finite differences, with Rayleigh mass and stiffness damping,
//! Tet4 and Tet10, cut, lumped and consistent mass), Newton converges
//! quadratically on it, and the iterations per step of the shipped
//! corotational dynamic scenes are pinned: the exact tangent
//! (c₀M + γ/(βΔt)Dₙ + K_exact) against R K Rᵀ.

use std::path::Path;
use xfem_cut::dynamics::{DynamicOptions, MassKind, Newmark};
use xfem_cut::model::{Model, NONE};
use xfem_cut::scene::{Analysis, Scene};
use xfem_cut::solve::Cholesky;

/// A shipped case at level 0 with `edit` applied to its text: the model and
/// the case's dynamic options.
fn case(file: &str, edit: (&str, &str)) -> (Model, DynamicOptions) {
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
    (model, options)
}

fn norm(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// `d` + `s` × `w` (w on the free equations).
fn moved(model: &Model, d: &[f64], w: &[f64], s: f64) -> Vec<f64> {
    let mut out = d.to_vec();
    for (dof, &eq) in model.equation.iter().enumerate() {
        if eq != NONE {
            out[dof] += s * w[eq as usize];
        }
    }
    out
}

/// The largest relative difference, over three directions w, between the
/// Newton matrix times w and the central difference (r(d − hw) − r(d + hw))/2h
/// of the residual, at an iterate of step 21 of `bend_dynamic` (in the ramp:
/// bent, moving, the cut open) with the given options.
fn tangent_error(model: &Model, options: DynamicOptions) -> f64 {
    let mut nm = Newmark::new(model, Cholesky::new(&model.pattern).unwrap(), options).unwrap();
    nm.initialise_acceleration().unwrap();
    for _ in 0..20 {
        nm.step().unwrap();
    }
    let n = model.n_free;
    let direction =
        |k: f64| -> Vec<f64> { (0..n).map(|i| (0.37 * k * i as f64 + k).sin()).collect() };
    // An iterate away from the predictor: dₙ + 1e-4 m × a direction.
    let d = moved(model, &nm.state.d.clone(), &direction(3.0), 1e-4);
    let (_, k) = nm.newton_system(&d);
    let h = 1e-7;
    let mut worst = 0.0f64;
    for j in [1.0, 2.0, 5.0] {
        let w = direction(j);
        let mut kw = vec![0.0; n];
        model.pattern.sym_mul_add(&k, &w, &mut kw);
        let (rm, _) = nm.newton_system(&moved(model, &d, &w, -h));
        let (rp, _) = nm.newton_system(&moved(model, &d, &w, h));
        let fd: Vec<f64> = rm
            .iter()
            .zip(&rp)
            .map(|(a, b)| (a - b) / (2.0 * h))
            .collect();
        let diff: Vec<f64> = kw.iter().zip(&fd).map(|(a, b)| a - b).collect();
        worst = worst.max(norm(&diff) / norm(&kw));
    }
    worst
}

/// The Newton matrix of a damped corotational step is the derivative of the
/// step's residual, f_ext − f_int − M a − Dₙ v with Dₙ = α M + β_R Rₙ K Rₙᵀ
/// (`bend_dynamic`'s α = 0.1, β_R = 0.01, Δt = 0.01): to ~1e-8 (the central
/// difference's error) on the cut beam, Tet4 and Tet10, lumped and
/// consistent mass. R K Rᵀ in place of the exact tangent (the seed's) is
/// caught: its error is the left-out geometric stiffness.
#[test]
fn the_damped_newton_matrix_is_the_residual_derivative() {
    for (element, mass) in [
        ("tet4", MassKind::Lumped),
        ("tet4", MassKind::Consistent),
        ("tet10", MassKind::Lumped),
    ] {
        let (model, options) = case(
            "bend_dynamic.toml",
            ("element = \"tet4\"", &format!("element = \"{element}\"")),
        );
        assert!(model.cut.is_some() && options.rayleigh_stiffness > 0.0);
        assert!(options.rayleigh_mass > 0.0);
        let exact = tangent_error(&model, DynamicOptions { mass, ..options });
        let corotated = tangent_error(
            &model,
            DynamicOptions {
                mass,
                exact_tangent: false,
                ..options
            },
        );
        println!(
            "{element} {mass:?} ({} free DOFs): exact tangent {exact:.2e}, R K Rᵀ {corotated:.2e}",
            model.n_free
        );
        assert!(exact < 1e-6, "{element} {mass:?}: {exact:e}");
        assert!(corotated > 100.0 * exact, "{element}: {corotated:e}");
    }
}

/// Newton on the step's system, from the predictor, by hand: the relative
/// residual of each iteration. Quadratic: each is at most ~C times the square
/// of the previous, down to round-off.
#[test]
fn damped_dynamics_newton_converges_quadratically() {
    let (model, options) = case("bend_dynamic.toml", ("", ""));
    let mut nm = Newmark::new(&model, Cholesky::new(&model.pattern).unwrap(), options).unwrap();
    nm.initialise_acceleration().unwrap();
    for _ in 0..30 {
        nm.step().unwrap();
    }
    let mut chol = Cholesky::new(&model.pattern).unwrap();
    let mut d = nm.state.d.clone();
    // The predictor: prescribed DOFs at t₃₁ (ramp 0.5 s).
    let ramp = ((nm.state.time + options.dt) / options.ramp).min(1.0);
    for p in &model.prescribed {
        d[p.dof] = ramp * p.value;
    }
    let mut history = Vec::new();
    for _ in 0..5 {
        let (mut r, k) = nm.newton_system(&d);
        history.push(norm(&r));
        if norm(&r) < 1e-12 * history[0] {
            break;
        }
        chol.factorize(&k).unwrap();
        chol.solve_in_place(&mut r);
        d = moved(&model, &d, &r, 1.0);
    }
    let rel: Vec<f64> = history.iter().map(|r| r / history[0]).collect();
    let shown: Vec<String> = rel.iter().map(|x| format!("{x:.2e}")).collect();
    println!("step 31, damped: |r_k| / |r_0| = {shown:?}");
    // Quadratic until round-off (≈1e-11 of |r_0| here): r_{k+1} ≤ 10 r_k².
    for k in 1..rel.len() {
        if rel[k] > 1e-10 {
            assert!(rel[k] <= 10.0 * rel[k - 1].powi(2), "{rel:?}");
        }
    }
    assert!(*rel.last().unwrap() < 1e-10, "{rel:?}");
    assert!(rel.len() <= 5, "{rel:?}");
}

/// A Newmark integrator of `model` with `options` and `linear_solver`
/// (AMD ordering, one thread), its initial acceleration computed.
fn integrator(
    model: &Model,
    options: DynamicOptions,
    linear_solver: xfem_cut::dynamics::LinearSolver,
) -> Newmark<'_> {
    let o = DynamicOptions {
        linear_solver,
        ..options
    };
    let mut nm = Newmark::new(model, Cholesky::new(&model.pattern).unwrap(), o).unwrap();
    nm.initialise_acceleration().unwrap();
    nm
}

/// Newton iterations of each of `steps` steps of a shipped case at level 0
/// (AMD ordering, one thread: deterministic), with `edit` applied to the case text.
fn iterations(file: &str, edit: (&str, &str), exact_tangent: bool, steps: usize) -> Vec<usize> {
    let (model, options) = case(file, edit);
    // Newton proper: refactorised every iteration (the scenes default to the
    // lagged factor, pinned in `the_default_lagged_step_of_the_shipped_scenes_is_pinned`).
    let options = DynamicOptions {
        exact_tangent,
        linear_solver: xfem_cut::dynamics::LinearSolver::Direct,
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

/// The shipped corotational dynamic scenes with Rayleigh damping (α = 0.1,
/// β_R = 0.01; `free_slice` ships undamped and gets the same damping here):
/// Newton on the exact tangent takes two or three iterations a step (it is
/// quadratic: `damped_dynamics_newton_converges_quadratically`), R K Rᵀ four
/// to seven. 60 steps of the bend cases (the 0.5 s ramp and 0.1 s after it),
/// the 30 steps of `free_slice` (the slice falls out from t = 0).
#[test]
fn damped_newton_iterations_of_the_shipped_scenes_are_pinned() {
    let damped = (
        "output_every = 5",
        "output_every = 5\nrayleigh = { mass = 0.1, stiffness = 0.01 }",
    );
    for (file, edit, steps) in [
        ("bend_dynamic.toml", ("", ""), 60),
        ("bend_dynamic_uncut.toml", ("", ""), 60),
        ("free_slice.toml", damped, 30),
    ] {
        let exact = iterations(file, edit, true, steps);
        let corotated = iterations(file, edit, false, steps);
        let (se, sc): (usize, usize) = (exact.iter().sum(), corotated.iter().sum());
        println!("{file}: exact {se} {:?}", runs(&exact));
        println!("{file}: R K Rᵀ {sc} {:?}", runs(&corotated));
        let want = match file {
            // The seed's front on the node plane x = 0.015 is held by the
            // elements behind it (tip nodes): R K Rᵀ takes 15 more.
            "bend_dynamic.toml" => (170, 299),
            "bend_dynamic_uncut.toml" => (170, 284),
            _ => (46, 72),
        };
        assert_eq!((se, sc), want, "{file}");
        assert!(*exact.iter().max().unwrap() <= 3, "{file}: {exact:?}");
    }
}

/// The shipped corotational dynamic scenes run modified Newton on a lagged
/// factor of the exact tangent by default ([`DEFAULT_LAGGED`]): every step
/// meets the scene's tolerance, the trajectory follows the refactorising
/// Newton step to the tolerance's level, and a factorisation serves many
/// steps. Pinned (AMD, one thread: deterministic): Newton iterations and
/// factorisations over the 60 steps of the bend cases' ramp and after it,
/// the 30 of `free_slice` — 363 / 17, 355 / 18 and 122 / 23 (362 / 17 for
/// `bend_dynamic` while the branch functions were √r, not √(r/h); the plain
/// modified Newton before the Anderson-accelerated default: 330 / 26,
/// 306 / 27 and 118 / 25), against 170, 170 and 89 factorisations
/// refactorising (one per iteration).
#[test]
fn the_default_lagged_step_of_the_shipped_scenes_is_pinned() {
    use xfem_cut::dynamics::{LinearSolver, DEFAULT_LAGGED};
    for (file, steps) in [
        ("bend_dynamic.toml", 60),
        ("bend_dynamic_uncut.toml", 60),
        ("free_slice.toml", 30),
    ] {
        let (model, options) = case(file, ("", ""));
        assert_eq!(options.linear_solver, DEFAULT_LAGGED, "{file}");
        let start = |linear_solver| integrator(&model, options, linear_solver);
        let (mut direct, mut lagged) = (start(LinearSolver::Direct), start(DEFAULT_LAGGED));
        let (mut newton, mut factorisations, mut worst) = (Vec::new(), 0, 0.0f64);
        for _ in 0..steps {
            direct.step().unwrap();
            let r = lagged.step().unwrap();
            assert!(r.residual <= options.tolerance, "{file}");
            newton.push(r.iterations);
            factorisations += r.factorisations;
            let diff: Vec<f64> = (direct.state.d.iter())
                .zip(&lagged.state.d)
                .map(|(a, b)| a - b)
                .collect();
            worst = worst.max(norm(&diff) / norm(&direct.state.d).max(1e-300));
        }
        let total: usize = newton.iter().sum();
        println!(
            "{file}: {total} Newton iterations, {factorisations} factorisations, max relative difference {worst:e}; {:?}",
            runs(&newton)
        );
        assert!(worst < 1e-7, "{file}: {worst:e}");
        let want = match file {
            "bend_dynamic.toml" => (363, 17),
            "bend_dynamic_uncut.toml" => (355, 18),
            _ => (122, 23),
        };
        assert_eq!((total, factorisations), want, "{file}");
    }
}

/// Issue 13's accuracy target for the fast step: over 1000 steps of
/// `bend_dynamic` (the ramp, then 9.5 s of damped motion) the default lagged
/// step stays within 1e-6 (relative, all DOFs) of the refactorising Newton
/// step, and its energy with it (measured: 2.0e-9 and 8.6e-11, 27
/// factorisations against the refactorising step's one or more a step).
#[test]
fn the_default_step_follows_the_refactorising_step_over_a_thousand_steps() {
    use xfem_cut::dynamics::{LinearSolver, DEFAULT_LAGGED};
    let (model, options) = case("bend_dynamic.toml", ("", ""));
    let start = |linear_solver| integrator(&model, options, linear_solver);
    let (mut direct, mut lagged) = (start(LinearSolver::Direct), start(DEFAULT_LAGGED));
    let (mut worst, mut worst_energy, mut factorisations) = (0.0f64, 0.0f64, 0);
    for _ in 0..1000 {
        direct.step().unwrap();
        factorisations += lagged.step().unwrap().factorisations;
        let diff: Vec<f64> = (direct.state.d.iter())
            .zip(&lagged.state.d)
            .map(|(a, b)| a - b)
            .collect();
        worst = worst.max(norm(&diff) / norm(&direct.state.d).max(1e-300));
        let (a, b) = (direct.energies(), lagged.energies());
        let (ea, eb) = (a.kinetic + a.strain, b.kinetic + b.strain);
        worst_energy = worst_energy.max((ea - eb).abs() / ea.abs().max(1e-300));
    }
    println!("1000 steps: max relative difference {worst:e}, energy {worst_energy:e}, {factorisations} factorisations");
    assert!(worst < 1e-6, "{worst:e}");
    assert!(worst_energy < 1e-6, "{worst_energy:e}");
    assert!(factorisations < 100, "{factorisations}");
}

/// The lagged default never fails a step Newton would finish: the last
/// three iterations a step may take (`dynamics::NEWTON_TAIL`) refactorise
/// each. With `max_iterations = 4` every step of `bend_dynamic`'s ramp (which
/// takes the lagged factor 5 to 7 iterations) still converges; with
/// `max_iterations = 1` the step is the linearly implicit one on the current
/// tangent, as with `direct`.
#[test]
fn the_lagged_default_keeps_the_iteration_limit_of_newton() {
    use xfem_cut::dynamics::{LinearSolver, DEFAULT_LAGGED};
    let (model, options) = case("bend_dynamic.toml", ("", ""));
    let start = |linear_solver, max_iterations| {
        let o = DynamicOptions {
            max_iterations,
            ..options
        };
        integrator(&model, o, linear_solver)
    };
    let mut tight = start(DEFAULT_LAGGED, 4);
    let mut factorisations = 0;
    for step in 0..60 {
        let r = tight.step().unwrap_or_else(|e| panic!("step {step}: {e}"));
        assert!(r.residual <= options.tolerance, "step {step}");
        assert!(r.iterations <= 4);
        factorisations += r.factorisations;
    }
    println!("max_iterations = 4: {factorisations} factorisations in 60 steps");
    let (mut lagged, mut direct) = (start(DEFAULT_LAGGED, 1), start(LinearSolver::Direct, 1));
    for step in 0..30 {
        let (a, b) = (lagged.step().unwrap(), direct.step().unwrap());
        assert_eq!((a.iterations, a.factorisations), (1, 1), "step {step}");
        assert_eq!((b.iterations, b.factorisations), (1, 1), "step {step}");
        assert_eq!(lagged.state.d, direct.state.d, "step {step}");
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

/// 100 steps of bend_dynamic at level 0 with `linear_solver` beside the
/// refactorising Newton step: (factorisations, CG iterations, Newton
/// iterations, largest relative difference of d over the run).
fn beside_direct(linear_solver: xfem_cut::dynamics::LinearSolver) -> (usize, usize, usize, f64) {
    use xfem_cut::dynamics::LinearSolver;
    let (model, options) = case("bend_dynamic.toml", ("", ""));
    let start = |linear_solver| integrator(&model, options, linear_solver);
    let mut direct = start(LinearSolver::Direct);
    let mut fast = start(linear_solver);
    let (mut worst, mut factorisations, mut cg, mut newton) = (0.0f64, 0, 0, 0);
    for _ in 0..100 {
        direct.step().unwrap();
        let r = fast.step().unwrap();
        assert!(r.residual <= options.tolerance);
        factorisations += r.factorisations;
        cg += r.cg_iterations;
        newton += r.iterations;
        let diff: Vec<f64> = (direct.state.d.iter())
            .zip(&fast.state.d)
            .map(|(a, b)| a - b)
            .collect();
        worst = worst.max(norm(&diff) / norm(&direct.state.d));
    }
    (factorisations, cg, newton, worst)
}

/// The step that reuses one factorisation (CG preconditioned by the warped
/// factor, refactorising only when CG needs more than 25 iterations) follows
/// the refactorising Newton step: 100 steps of bend_dynamic at level 0.
#[test]
fn the_warped_pcg_step_follows_the_refactorising_step() {
    use xfem_cut::dynamics::LinearSolver;
    let (factorisations, cg, newton, worst) = beside_direct(LinearSolver::WarpedPcg {
        tolerance: 1e-10,
        max_cg: 25,
    });
    println!(
        "warped PCG: {factorisations} factorisations, {cg} CG iterations, {newton} Newton iterations in 100 steps; max relative difference {worst:e}"
    );
    assert!(worst < 1e-9, "{worst:e}");
    assert!(factorisations <= 5, "{factorisations}");
}

/// Modified Newton on a factor kept for k steps (refactorised after 8
/// iterations on one factor): converges to the scene's tolerance every step
/// and follows the refactorising step to the Newton tolerance's level, with
/// about 1/k factorisations a step.
#[test]
fn the_lagged_factor_step_follows_the_refactorising_step() {
    use xfem_cut::dynamics::LinearSolver;
    for every in [1, 5, 20] {
        let (factorisations, cg, newton, worst) = beside_direct(LinearSolver::Lagged {
            every,
            refactor_after: 8,
            max_rate: 1.0,
            anderson: 0,
        });
        println!(
            "lagged k = {every}: {factorisations} factorisations, {newton} Newton iterations in 100 steps; max relative difference {worst:e}"
        );
        assert_eq!(cg, 0);
        assert!(worst < 1e-7, "k = {every}: {worst:e}");
        // Pinned (AMD, one thread): 100, 24 and 16 — the age's 100 / k and
        // the refactorisations after 8 iterations on one factor in the ramp.
        let want = match every {
            1 => 100,
            5 => 24,
            _ => 16,
        };
        assert_eq!(factorisations, want, "k = {every}");
    }
}

/// The default lagged step (refactorised when an iteration leaves more than
/// 0.2 of the residual or after 12 on one factor, Anderson-accelerated after
/// one that left more than 0.1) follows the refactorising step to the
/// Newton tolerance's level over 100 steps of `bend_dynamic`, and its
/// acceleration saves iterations: the same policy without it takes more
/// Newton iterations. Pinned (deterministic): 447 iterations and 17
/// factorisations against 451 and 17 (467 and 16 while the cells the front
/// crossed off their edges, on the node plane x = 0.015, took the red
/// refinement's rule, not a split onto the front:
/// [`xfem_cut::model::ElementShapes::cell_rule`]; 442 and 17 against 451 and 17 while
/// the branch functions were √r, not √(r/h): Newton's norms weighed the tip
/// rows otherwise, [`xfem_cut::cut::CutSetup::tip_scale`]; one
/// factorisation more for 20 iterations fewer is about even at this size,
/// where a factorisation with its tangent costs a few iterations.)
#[test]
fn the_default_anderson_accelerated_lagged_step_follows_the_refactorising_step() {
    use xfem_cut::dynamics::{LinearSolver, DEFAULT_LAGGED};
    let LinearSolver::Lagged {
        every,
        refactor_after,
        max_rate,
        anderson,
    } = DEFAULT_LAGGED
    else {
        panic!("the default is lagged");
    };
    assert!(anderson > 0);
    let (f_aa, cg, n_aa, worst) = beside_direct(DEFAULT_LAGGED);
    let (f_plain, _, n_plain, worst_plain) = beside_direct(LinearSolver::Lagged {
        every,
        refactor_after,
        max_rate,
        anderson: 0,
    });
    println!(
        "Anderson: {f_aa} factorisations, {n_aa} Newton iterations in 100 steps, max relative difference {worst:e}; plain: {f_plain}, {n_plain}, {worst_plain:e}"
    );
    assert_eq!(cg, 0);
    assert!(worst < 1e-7, "{worst:e}");
    assert!(worst_plain < 1e-7, "{worst_plain:e}");
    assert!(n_aa < n_plain, "{n_aa} vs {n_plain}");
    assert_eq!((n_aa, f_aa, n_plain, f_plain), (447, 17, 451, 17));
}

/// `bend_dynamic` (corotational, Rayleigh mass and stiffness damping) at
/// large steps: once the prescribed edge stops (0.5 s) no work enters, so
/// the damped energy ½vᵀMv + W never grows, and the prescribed DOFs move as
/// prescribed — velocity p̄/ramp inside the ramp, zero after it. Newmark's
/// own kinematics of those DOFs ring after the ramp (the trapezoidal rule
/// flips v each step once d stops), and the damping Rₙ K Rₙᵀ v, whose
/// rotations change every step, fed that ringing into the body: E grew by
/// 2.5e-3 at dt = 0.1 s.
#[test]
fn damped_energy_never_grows_after_the_ramp_at_large_steps() {
    for dt in ["0.1", "0.05"] {
        let (model, options) = case("bend_dynamic.toml", ("dt = 0.01", &format!("dt = {dt}")));
        let mut nm = Newmark::new(&model, Cholesky::new(&model.pattern).unwrap(), options).unwrap();
        nm.initialise_acceleration().unwrap();
        let mut after_ramp: Vec<f64> = Vec::new();
        while nm.state.time < 1.0 - 1e-9 {
            nm.step().unwrap();
            let t = nm.state.time;
            let rate = if t < options.ramp - 1e-9 {
                1.0 / options.ramp
            } else {
                0.0
            };
            for p in &model.prescribed {
                assert!(
                    (nm.state.v[p.dof] - rate * p.value).abs() <= 1e-12 * p.value.abs().max(1.0)
                );
                assert_eq!(nm.state.a[p.dof], 0.0);
            }
            if t >= options.ramp - 1e-9 {
                let e = nm.energies();
                after_ramp.push(e.kinetic + e.strain);
            }
        }
        assert!(after_ramp.len() >= 5, "dt = {dt}");
        for w in after_ramp.windows(2) {
            assert!(
                w[1] <= w[0] * (1.0 + 1e-9),
                "dt = {dt}: E {:e} → {:e}",
                w[0],
                w[1]
            );
        }
    }
}

#[test]
fn a_step_newton_cannot_take_whole_is_taken_in_halves() {
    // A random scene's: ν = 0.49, Tet10, corotational, stiffness damping,
    // the top face moved by 7.8 mm (4 % of the beam) in the first step.
    // Newton failed at the second step (relative residual 0.46, five groups
    // inverted with the lagged factor); the step is now taken as two
    // halves, and those are the two steps an integrator of Δt/2 takes from
    // the same state.
    let text = r#"
name = "halves"
[body]
box = [[0.0, 0.0, 0.0], [0.03, 0.06, 0.2]]
levels = [[2, 3, 8]]
element = "tet10"
[material]
young = 1.0e5
poisson = 0.49
density = 1070.0
[[fix]]
min = [-inf, -inf, 0.0]
max = [inf, inf, 0.0]
[[fix]]
min = [-inf, -inf, 0.2]
max = [inf, inf, 0.2]
displacement = [0.0, 0.0, 0.0078]
[analysis]
type = "dynamic"
formulation = "corotational"
dt = 0.01
steps = 8
mass = "lumped"
linear_solver = "direct"
rayleigh = { mass = 0.0, stiffness = 0.001 }
"#;
    let scene = Scene::parse(text, Path::new("halves.toml")).unwrap();
    let (model, _) = scene.build(scene.mesh(0).unwrap()).unwrap();
    let Analysis::Dynamic { options, .. } = scene.analysis else {
        panic!("a dynamic scene")
    };
    let mut nm = Newmark::new(&model, Cholesky::new(&model.pattern).unwrap(), options).unwrap();
    nm.initialise_acceleration().unwrap();
    assert_eq!(nm.step().unwrap().substeps, 0);
    let after_first = nm.state.clone();
    let second = nm.step().unwrap();
    println!("second step: {second:?}");
    assert_eq!(second.substeps, 1, "the second step is taken in two halves");
    let half = DynamicOptions {
        dt: 0.5 * options.dt,
        ..options
    };
    let mut nh = Newmark::new(&model, Cholesky::new(&model.pattern).unwrap(), half).unwrap();
    nh.state = after_first;
    let (a, b) = (nh.step().unwrap(), nh.step().unwrap());
    assert_eq!((a.substeps, b.substeps), (0, 0));
    // The whole step's failed attempt took all its iterations, then the halves.
    assert_eq!(
        options.max_iterations + a.iterations + b.iterations,
        second.iterations
    );
    let scale = nh.state.d.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = nm
        .state
        .d
        .iter()
        .zip(&nh.state.d)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    assert!(diff <= 1e-12 * scale, "{diff:e} of {scale:e}");
    assert!((nm.state.time - nh.state.time).abs() < 1e-15);
    // The rest of the run goes on.
    for _ in 2..8 {
        nm.step().unwrap();
    }
}

/// What `run` shows while it solves (`run::solve_scene_observed`): the
/// plan first, before the solve (the one the result holds; a blade's, whose
/// models are built as it runs, with the sizes of its start), then: a static corotational scene reports every residual its Newton iterations
/// evaluate, the last being the solution's, at the full load; a dynamic
/// scene and a blade's sweep report each step once, in order, the last at
/// the final time. The solution is the one `solve_scene` gives.
#[test]
fn a_run_reports_where_it_is() {
    use xfem_cut::run::{solve_scene, solve_scene_observed, Progress};
    use xfem_cut::solve::Parallelism;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let load = |file: &str, edits: &[(&str, &str)]| {
        let path = root.join(file);
        let mut text = std::fs::read_to_string(&path).unwrap();
        for (from, to) in edits {
            assert!(text.contains(from), "{file}: {from}");
            text = text.replacen(from, to, 1);
        }
        Scene::parse(&text, &path).unwrap()
    };
    // What was reported after the plan, and whether the plan came (first).
    let observed =
        |scene: &Scene| {
            let (mut plan, mut seen) = (None, Vec::new());
            let r =
                solve_scene_observed(scene, 0, None, false, Parallelism::SEQUENTIAL, &mut |p| {
                    match p {
                        Progress::Planned(p) => {
                            assert!(
                                plan.is_none() && seen.is_empty(),
                                "the plan comes first, once"
                            );
                            plan = Some(p.to_string());
                        }
                        Progress::Newton(n) => seen.push(Progress::Newton(n)),
                        Progress::Step { step, steps, time } => {
                            seen.push(Progress::Step { step, steps, time })
                        }
                    }
                })
                .unwrap();
            let plain = solve_scene(scene, 0, None, false).unwrap();
            assert_eq!(
                r.d, plain.d,
                "{}: observing changed the solution",
                scene.name
            );
            if let Some(plan) = &plan {
                // A blade's plan is its start's: the stages the result's,
                // the sizes those of the model before the blade enters.
                let (stages, size) = plan.split_once("\nsize").unwrap();
                let whole = r.plan.to_string();
                let (result_stages, _) = whole.split_once("\nsize").unwrap();
                assert_eq!(stages, result_stages, "{}", scene.name);
                if scene.has_blade() {
                    assert!(size.starts_with(" at the start"), "{}: {size}", scene.name);
                } else {
                    assert_eq!(plan, &whole, "{}", scene.name);
                }
            }
            (r, seen, plan.is_some())
        };
    // Static, corotational: Newton's residuals.
    let scene = load(
        "bend.toml",
        &[(
            r#"formulation = "linear""#,
            r#"formulation = "corotational""#,
        )],
    );
    let (r, seen, planned) = observed(&scene);
    assert!(planned, "a static scene's plan comes before its solve");
    let newton: Vec<_> = seen
        .iter()
        .map(|p| match p {
            Progress::Newton(n) => *n,
            other => panic!("a static scene reported {other:?}"),
        })
        .collect();
    let iterations: usize = r.iterations.iter().sum();
    println!(
        "bend corotational: {} residuals for {iterations} iterations over {} load steps",
        newton.len(),
        r.iterations.len()
    );
    // One residual before each iteration's solve and one that ends each
    // step (no step halved here).
    assert_eq!(r.cutbacks, 0);
    assert_eq!(newton.len(), iterations + r.iterations.len());
    let last = newton.last().unwrap();
    assert_eq!((last.lambda, last.residual), (1.0, r.residual));
    assert!(newton.windows(2).all(|w| w[1].lambda >= w[0].lambda));
    // Dynamic, and a blade's sweep: each step once.
    for (file, edits) in [
        ("bend_dynamic.toml", &[("steps = 10000", "steps = 60")][..]),
        ("cut_progressive.toml", &[("steps = 300", "steps = 70")][..]),
    ] {
        let scene = load(file, edits);
        let Analysis::Dynamic { options, .. } = scene.analysis else {
            panic!("{file}: a dynamic scene")
        };
        let (_, seen, planned) = observed(&scene);
        assert!(planned, "{file}: the plan comes before the steps");
        let steps: Vec<(usize, f64)> = seen
            .iter()
            .map(|p| match p {
                Progress::Step { step, steps, time } => {
                    assert_eq!(*steps, options.steps);
                    (*step, *time)
                }
                other => panic!("{file}: a dynamic scene reported {other:?}"),
            })
            .collect();
        println!("{file}: {} steps reported", steps.len());
        assert_eq!(
            steps.iter().map(|s| s.0).collect::<Vec<_>>(),
            (1..=options.steps).collect::<Vec<_>>(),
            "{file}"
        );
        let t_end = options.dt * options.steps as f64;
        assert!(
            (steps.last().unwrap().1 - t_end).abs() <= 1e-9 * t_end,
            "{file}"
        );
    }
}
