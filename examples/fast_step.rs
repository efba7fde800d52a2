//! The corotational step that reuses one factorisation, measured against the
//! refactorising Newton step on a shipped dynamic case: per-step Newton and
//! CG iterations, factorisations, time, and the trajectory's relative
//! difference (all DOFs and the energy) over the run.
//!
//! Modes: the refactorising Newton (the reference), CG on the lagged and on
//! the warped factor, and modified Newton on a factor kept for k = 1, 5, 20
//! steps (refactorised after `refactor_after` iterations on one factor),
//! by rate, the default ([`DEFAULT_LAGGED`]: Anderson-accelerated) and the
//! default before it (plain modified Newton, refactorised below a 10×
//! reduction or after 8 iterations on one factor).
//! Energy: the largest relative difference of kinetic + strain energy from
//! the reference's, and each mode's change of kinetic + strain energy from
//! the end of the ramp (constant loads from there) to the last step (with
//! damping it decays; without, it is the drift).
//!
//! `cargo run --release --example fast_step -- cases/bend_dynamic.toml 1 1000 [max_cg] [CG tolerance] [refactor_after]`
use std::path::Path;
use std::time::Instant;
use xfem_cut::assembly::equation_shapes;
use xfem_cut::dynamics::{DynamicOptions, LinearSolver, Newmark, DEFAULT_LAGGED};
use xfem_cut::scene::{Analysis, Scene};
use xfem_cut::solve::{Cholesky, Parallelism};

/// The allocator the `xfem-cut` binary and the benches run with (see
/// `src/main.rs`), so that what this times is what a run pays.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let file = args
        .first()
        .map_or("cases/bend_dynamic.toml", |s| s.as_str());
    let level: usize = args.get(1).map_or(0, |s| s.parse().expect("level"));
    let steps: usize = args.get(2).map_or(1000, |s| s.parse().expect("steps"));
    let max_cg: usize = args.get(3).map_or(25, |s| s.parse().expect("max CG"));
    let cg_tolerance: f64 = args
        .get(4)
        .map_or(1e-10, |s| s.parse().expect("CG tolerance"));
    // Lagged factor: refactorise after this many Newton iterations on one factor in a step.
    let lag_after: usize = args
        .get(5)
        .map_or(8, |s| s.parse().expect("refactor after"));
    let scene = Scene::load(Path::new(file)).expect("case loads");
    let (model, _) = scene
        .build(scene.mesh(level).expect("mesh"))
        .expect("model");
    let Analysis::Dynamic { options, .. } = scene.analysis else {
        panic!("{file} is not dynamic")
    };
    println!(
        "{file} level {level}: {} tets, {} free DOFs, {steps} steps, Newton tolerance {:e}, CG tolerance {cg_tolerance:e}, max CG {max_cg}",
        model.mesh.n_elements(),
        model.n_free,
        options.tolerance
    );
    let modes = [
        ("refactorising Newton", LinearSolver::Direct),
        (
            "lagged factor + PCG",
            LinearSolver::Pcg {
                tolerance: cg_tolerance,
                max_cg,
            },
        ),
        (
            "warped factor + PCG",
            LinearSolver::WarpedPcg {
                tolerance: cg_tolerance,
                max_cg,
            },
        ),
        (
            "lagged k=1",
            LinearSolver::Lagged {
                every: 1,
                refactor_after: lag_after,
                max_rate: 1.0,
                anderson: 0,
            },
        ),
        (
            "lagged k=5",
            LinearSolver::Lagged {
                every: 5,
                refactor_after: lag_after,
                max_rate: 1.0,
                anderson: 0,
            },
        ),
        (
            "lagged k=20",
            LinearSolver::Lagged {
                every: 20,
                refactor_after: lag_after,
                max_rate: 1.0,
                anderson: 0,
            },
        ),
        (
            "adaptive 0.1",
            LinearSolver::Lagged {
                every: usize::MAX,
                refactor_after: lag_after,
                max_rate: 0.1,
                anderson: 0,
            },
        ),
        (
            "adaptive 0.3",
            LinearSolver::Lagged {
                every: usize::MAX,
                refactor_after: lag_after,
                max_rate: 0.3,
                anderson: 0,
            },
        ),
        (
            "adaptive 0.03",
            LinearSolver::Lagged {
                every: usize::MAX,
                refactor_after: lag_after,
                max_rate: 0.03,
                anderson: 0,
            },
        ),
        ("default (Anderson)", DEFAULT_LAGGED),
        (
            "old default",
            LinearSolver::Lagged {
                every: usize::MAX,
                refactor_after: 8,
                max_rate: 0.1,
                anderson: 0,
            },
        ),
    ];
    let blocks = equation_shapes(&model);
    let mut runs: Vec<_> = modes
        .iter()
        .map(|&(_, linear_solver)| {
            let chol =
                Cholesky::fill_reducing(&model.pattern, Some(&blocks), Parallelism::SEQUENTIAL)
                    .expect("symbolic");
            let mut nm = Newmark::new(
                &model,
                chol,
                DynamicOptions {
                    linear_solver,
                    ..options
                },
            )
            .expect("integrator");
            nm.initialise_acceleration().expect("initial acceleration");
            nm
        })
        .collect();
    let n = modes.len();
    let (mut newton, mut cg, mut facts) = (vec![0; n], vec![0; n], vec![0; n]);
    let mut times: Vec<Vec<f64>> = vec![Vec::with_capacity(steps); n];
    let (mut d_diff, mut e_diff): (Vec<f64>, Vec<f64>) = (vec![0.0; n], vec![0.0; n]);
    // Energy drift: kinetic + strain from the end of the ramp (loads constant from there) to the end.
    let ramp_end = ((options.ramp / options.dt).ceil() as usize).min(steps - 1);
    let (mut e_first, mut e_last) = (vec![0.0; n], vec![0.0; n]);
    for step in 0..steps {
        for (k, nm) in runs.iter_mut().enumerate() {
            let t = Instant::now();
            let r = nm.step().expect("step");
            times[k].push(t.elapsed().as_secs_f64() * 1e3);
            newton[k] += r.iterations;
            cg[k] += r.cg_iterations;
            facts[k] += r.factorisations;
            if step == ramp_end || step + 1 == steps {
                let e = nm.energies();
                let total = e.kinetic + e.strain;
                if step == ramp_end {
                    e_first[k] = total;
                }
                e_last[k] = total;
            }
        }
        let (reference, rest) = runs.split_first_mut().expect("modes");
        let e_ref = reference.energies();
        let d_ref = &reference.state.d;
        let d_norm = d_ref.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-300);
        let e_ref_total = e_ref.kinetic + e_ref.strain;
        for (k, nm) in rest.iter_mut().enumerate() {
            let diff = nm
                .state
                .d
                .iter()
                .zip(d_ref)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt();
            d_diff[k + 1] = d_diff[k + 1].max(diff / d_norm);
            let e = nm.energies();
            let de = ((e.kinetic + e.strain) - e_ref_total).abs() / e_ref_total.abs().max(1e-300);
            e_diff[k + 1] = e_diff[k + 1].max(de);
        }
    }
    println!("mode                 | Newton/step | CG/step | fact./step | ms/step median  mean   max | max rel. diff d   energy | E_end/E_ramp − 1");
    for (k, (name, _)) in modes.iter().enumerate() {
        times[k].sort_by(f64::total_cmp);
        println!(
            "{name:20} | {:>11.2} | {:>7.2} | {:>10.3} | {:>13.3} {:>5.3} {:>5.1} | {:>15.2e} {:>8.2e} | {:>13.6e}",
            newton[k] as f64 / steps as f64,
            cg[k] as f64 / steps as f64,
            facts[k] as f64 / steps as f64,
            times[k][steps / 2],
            times[k].iter().sum::<f64>() / steps as f64,
            times[k][steps - 1],
            d_diff[k],
            e_diff[k],
            e_last[k] / e_first[k] - 1.0
        );
    }
}
