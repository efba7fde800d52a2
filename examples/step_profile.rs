//! What a corotational Newmark step costs, part by part, on the seed beam
//! (bottom clamped, gravity across, lumped mass, exact tangent, Newton to
//! 1e-8): 1k and 10k Tet4, 1k Tet10. Medians of repeated calls, one thread.
//!
//! Parts: the rotations alone (polar decompositions, warm started from the
//! converged rotations, and from the previous step's), forces + rotations,
//! forces + rotations + exact tangent in one pass, the exact tangent alone
//! with the rotations held (what a Newton iteration assembles after its
//! forces pass),
//! R K Rᵀ with the rotations held (the damping's Rₙ K Rₙᵀ), one product
//! R K Rᵀ v (the damping force), one pass over the element data (the memory
//! floor, `assembly::element_data_pass`), the numeric factorisation of K_eff
//! and one solve with it; then a whole step as the integrator takes it (from
//! the state after 10 steps, restored before each) with its Newton
//! iterations, and the step rebuilt from the parts; last, 20 steps from that
//! state with each linear solver (refactorising, warped PCG, lagged factor
//! k = 5, 20, and the default: Anderson-accelerated, refactorised by rate;
//! `steps=N` for N steps instead of 20).
//!
//! `cargo run --release --example step_profile` (all three), or
//! `-- 6 12 24 [tet10] [tip|extend] [radius=R [ramp]] [steps=N]` for one
//! beam (`tip`: the seed's cut shortened to x = 0.0137, its front inside
//! elements and tip-enriched, as in the `tip` group of benches/cut.rs,
//! within R of the front with `radius=R`, its blending elements not ramped
//! unless `ramp` (a case ramps them where R ≥ 2.5 median edges,
//! `cut::RAMP_SPAN`); `extend`: the same cut extended to the faces
//! of its front elements, what that group compares it with).
use nalgebra::{Point3, Vector3};
use std::hint::black_box;
use std::time::Instant;
use xfem_cut::assembly::{
    element_data_bytes, element_data_pass, equation_shapes, evaluate, tangent_product, Request,
    Workspace,
};
use xfem_cut::cut::{setup_cut, CutInput, PlanarPatch, DEFAULT_SNAP};
use xfem_cut::dynamics::{DynamicOptions, LinearSolver, Newmark, DEFAULT_LAGGED};
use xfem_cut::model::{Formulation, Model};
use xfem_cut::solve::{Cholesky, Parallelism};
use xfem_cut::study::fixtures::{beam_mesh, seed_beam};

/// The allocator the `xfem-cut` binary and the benches run with (see
/// `src/main.rs`), so that what this times is what a run pays.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Median wall time (ms) of `f` over repeated calls (≥ 5, about 0.4 s in all).
fn median_ms(mut f: impl FnMut()) -> f64 {
    let t = Instant::now();
    f();
    let once = t.elapsed().as_secs_f64();
    let reps = ((0.4 / once.max(1e-9)) as usize).clamp(5, 400);
    let mut times: Vec<f64> = (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[reps / 2]
}

fn profile(div: [usize; 3], tet10: bool, front: Option<&str>) {
    let mesh = beam_mesh(div, tet10);
    let cut = front.map(|front| {
        let patch = PlanarPatch {
            origin: Point3::new(0.0, 0.0, 0.1),
            u: Vector3::new(0.0137, 0.0, 0.0),
            v: Vector3::new(0.0, 0.06, 0.0),
        };
        let input = if front == "extend" {
            CutInput::extend(&patch, DEFAULT_SNAP)
        } else {
            // `radius=R`: geometric, with the blending a case's cut takes
            // (none), or the ramp with `ramp`.
            let radius = radius();
            let blending = if std::env::args().any(|a| a == "ramp") {
                xfem_cut::cut::Blending::Ramp
            } else {
                xfem_cut::cut::Blending::for_cut(xfem_cut::cut::FrontMode::Tip, radius, mesh.kind)
            };
            CutInput {
                blending,
                ..CutInput::tip(&patch, DEFAULT_SNAP, radius)
            }
        };
        setup_cut(&mesh, &[input]).unwrap()
    });
    let n_tip = cut.as_ref().map_or(0, |c| c.n_tip());
    let m: Model = seed_beam(mesh, Formulation::Corotational, cut).unwrap();
    let kind = if tet10 { "Tet10" } else { "Tet4" };
    println!(
        "\n{} {kind} ({} free DOFs, {} groups, {} dense, {n_tip} tip nodes): element data {:.1} MB, factor {} entries",
        m.mesh.n_elements(),
        m.n_free,
        m.groups.len(),
        m.groups.iter().filter(|g| g.is_dense()).count(),
        element_data_bytes(&m) as f64 / 1e6,
        Cholesky::fill_reducing(&m.pattern, Some(&equation_shapes(&m)), Parallelism::SEQUENTIAL)
            .unwrap()
            .factor_nnz()
    );
    let opts = DynamicOptions::default();
    let chol = Cholesky::fill_reducing(
        &m.pattern,
        Some(&equation_shapes(&m)),
        Parallelism::SEQUENTIAL,
    )
    .unwrap();
    let mut nm = Newmark::new(&m, chol, opts).unwrap();
    nm.initialise_acceleration().unwrap();
    for _ in 0..9 {
        nm.step().unwrap();
    }
    let previous = nm.state.rotations.clone();
    nm.step().unwrap();
    let saved = nm.state.clone();
    let d = saved.d.clone();
    let mut ws = Workspace::new(&m);
    let mut rot = saved.rotations.clone();
    let mut f = vec![0.0; m.n_dofs()];
    let mut k = vec![0.0; m.pattern.nnz()];
    let mut pass = |forces: bool, tangent: bool, update: bool, exact: bool| {
        let (f, k) = (&mut f, &mut k);
        black_box(evaluate(
            &m,
            &d,
            &mut rot,
            &mut ws,
            Request {
                forces: forces.then_some(&mut f[..]),
                tangent: tangent.then_some(&mut k[..]),
                update_rotations: update,
                exact_tangent: exact,
            },
        ));
    };
    let rotations = median_ms(|| pass(false, false, true, false));
    // The rotations from the previous step's (a step's first polar decompositions).
    let mut rot_prev = previous.clone();
    let mut ws_prev = Workspace::new(&m);
    let rotations_moved = median_ms(|| {
        rot_prev.0.copy_from_slice(&previous.0);
        black_box(evaluate(
            &m,
            &d,
            &mut rot_prev,
            &mut ws_prev,
            Request {
                forces: None,
                tangent: None,
                update_rotations: true,
                exact_tangent: false,
            },
        ));
    });
    let forces = median_ms(|| pass(true, false, true, false));
    let assembly = median_ms(|| pass(true, true, true, true));
    let held = median_ms(|| pass(false, true, false, false));
    let tangent = median_ms(|| pass(false, true, false, true));
    let mut y = vec![0.0; m.n_dofs()];
    let product = median_ms(|| {
        y.fill(0.0);
        tangent_product(&m, &saved.v, &saved.rotations, &mut ws, &mut y)
    });
    let floor = median_ms(|| {
        f.fill(0.0);
        k.fill(0.0);
        black_box(element_data_pass(&m, &d, &mut f, &mut k));
    });
    let (r, keff) = nm.newton_system(&d);
    let mut chol = Cholesky::fill_reducing(
        &m.pattern,
        Some(&equation_shapes(&m)),
        Parallelism::SEQUENTIAL,
    )
    .unwrap();
    let factor = median_ms(|| chol.factorize(&keff).unwrap());
    let mut x = r.clone();
    let solve = median_ms(|| {
        x.copy_from_slice(&r);
        chol.solve_in_place(&mut x)
    });
    let mut iterations = 0;
    let step = median_ms(|| {
        nm.state.clone_from(&saved);
        iterations = nm.step().unwrap().iterations;
    });
    println!(
        "  rotations {rotations:.3} ms (from the previous step's {rotations_moved:.3}) | forces + rotations {forces:.3} | + exact tangent {assembly:.3} | R K Rᵀ held {held:.3} | R K Rᵀ v {product:.3} | element-data pass {floor:.3} ({:.1} GB/s)",
        element_data_bytes(&m) as f64 / (floor * 1e6)
    );
    println!(
        "  factorisation {factor:.3} ms (nnz(L) = {}) | solve {solve:.3}",
        chol.factor_nnz()
    );
    // A step: `iterations` Newton iterations, each a forces pass (with the
    // rotations), a tangent pass (rotations held), a factorisation and a
    // solve, and one more forces pass that finds the residual converged.
    let (its, passes) = (iterations as f64, (iterations + 1) as f64);
    let assembled = passes * forces + its * tangent;
    let parts = assembled + its * (factor + solve);
    println!(
        "  exact tangent alone (rotations held) {tangent:.3} ms; step {step:.3} ms with {iterations} Newton iterations; from the parts {parts:.3}: assembly {:.0} %, factorisation {:.0} %, solves {:.0} %; assembly / floor {:.1}×",
        100.0 * assembled / parts,
        100.0 * iterations as f64 * factor / parts,
        100.0 * iterations as f64 * solve / parts,
        assembly / floor
    );
    modes(&m, &saved);
}

/// [`steps`] consecutive steps from `state` with each linear solver: median
/// and mean ms a step, Newton iterations and factorisations a step.
fn modes(m: &Model, state: &xfem_cut::dynamics::State) {
    let lagged = |every| LinearSolver::Lagged {
        every,
        refactor_after: 8,
        max_rate: 1.0,
        anderson: 0,
    };
    for (name, linear_solver) in [
        ("refactorising Newton", LinearSolver::Direct),
        (
            "warped PCG",
            LinearSolver::WarpedPcg {
                tolerance: 1e-10,
                max_cg: 50,
            },
        ),
        ("lagged k = 5", lagged(5)),
        ("lagged k = 20", lagged(20)),
        ("lagged (the default)", DEFAULT_LAGGED),
    ] {
        let chol = Cholesky::fill_reducing(
            &m.pattern,
            Some(&equation_shapes(m)),
            Parallelism::SEQUENTIAL,
        )
        .unwrap();
        let opts = DynamicOptions {
            linear_solver,
            ..DynamicOptions::default()
        };
        let mut nm = Newmark::new(m, chol, opts).unwrap();
        nm.state.clone_from(state);
        let n = steps();
        let (mut times, mut newton, mut facts, mut cg) = (Vec::new(), 0, 0, 0);
        for _ in 0..n {
            let t = Instant::now();
            let r = nm.step().unwrap();
            times.push(t.elapsed().as_secs_f64() * 1e3);
            newton += r.iterations;
            facts += r.factorisations;
            cg += r.cg_iterations;
        }
        times.sort_by(f64::total_cmp);
        println!(
            "  {name:20}: {:.3} ms a step (median of {n}; mean {:.3}), {:.2} Newton, {:.1} CG, {:.2} factorisations a step",
            times[n / 2],
            times.iter().sum::<f64>() / n as f64,
            newton as f64 / n as f64,
            cg as f64 / n as f64,
            facts as f64 / n as f64
        );
    }
}

/// The tip front's `tip_radius`: `radius=R` among the arguments, else none (topological).
fn radius() -> Option<f64> {
    std::env::args().find_map(|a| {
        a.strip_prefix("radius=")
            .map(|r| r.parse().expect("radius"))
    })
}

/// Steps of each linear solver's run: `steps=N` among the arguments, else 20.
fn steps() -> usize {
    std::env::args()
        .find_map(|a| a.strip_prefix("steps=").map(|n| n.parse().expect("steps")))
        .unwrap_or(20)
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() >= 3 {
        let div = [0, 1, 2].map(|i| args[i].parse().expect("divisions"));
        let flag = |f: &str| args[3..].iter().any(|a| a == f);
        let front = ["tip", "extend"].into_iter().find(|f| flag(f));
        profile(div, flag("tet10"), front);
        return;
    }
    println!("seed beam, corotational, exact tangent, lumped mass, one thread (medians; the machine may be shared)");
    profile([3, 6, 10], false, None);
    profile([6, 12, 24], false, None);
    profile([3, 6, 10], true, None);
}
