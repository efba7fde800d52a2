//! A tip front's cut event on the seed's beam, part by part: a blade opening
//! the seed's cut during [0, 1] s, its front tip-enriched (the default), the
//! event from t = 0.5 to 0.5 + dt: the set-up at the new time, the model
//! update (the elements holding branch functions integrated again; beside
//! it the update of the same model built whole, which integrates their old
//! blocks again too), and the state mapped (the least-squares projection);
//! beside them the update that takes the projection's integrals of the
//! tip elements on its way and the projection left after it (what a sweep
//! runs, `Model::update_cut_fitted_with`, `map_state_fitted_with`) with
//! its difference from the separate projection; medians of repeated calls,
//! one thread, with the number of elements integrated again and the
//! quadrature points they hold.
//!
//! With `threads=N`, the update and the projection also run on N threads
//! (`Model::update_cut_mapped_with`, `map_state_reported_with`).
//!
//! `cargo run --release --example tip_event -- 3 6 10 [tet10] [reps] [threads=N]`
use std::time::Instant;
use xfem_cut::blade::{map_state_fitted_with, map_state_reported_with, CutSet};
use xfem_cut::cut::FrontMode;
use xfem_cut::dynamics::{DynamicOptions, Newmark};
use xfem_cut::model::Formulation;
use xfem_cut::solve::{Cholesky, Parallelism};
use xfem_cut::study::fixtures::{beam_mesh, seed_beam, seed_blade};

/// The allocator the `xfem-cut` binary and the benches run with (see
/// `src/main.rs`), so that what this times is what a run pays.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn median(mut f: impl FnMut(), reps: usize) -> f64 {
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[reps / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let div = [0, 1, 2].map(|i| args.get(i).map_or(3, |a| a.parse().expect("divisions")));
    let tet10 = args.iter().any(|a| a == "tet10");
    let threads: usize = args
        .iter()
        .find_map(|a| a.strip_prefix("threads="))
        .map_or(1, |n| n.parse().expect("threads"));
    let reps: usize = args
        .get(3)
        .filter(|a| *a != "tet10" && !a.starts_with("threads="))
        .map_or(7, |a| a.parse().expect("repetitions"));
    let par = Parallelism::threads(threads);
    let mesh = beam_mesh(div, tet10);
    let cuts = CutSet {
        front: FrontMode::Tip,
        ..seed_blade(0.0, 1.0)
    };
    let dt = 0.005;
    let (t_a, t_b) = (0.5, 0.5 + dt);
    let setup_a = cuts.setup_at(&mesh, t_a).unwrap();
    let setup_b = cuts.setup_at(&mesh, t_b).unwrap();
    // The model at t_a as a sweep has it: updated from the step before
    // (what the previous event integrated is kept for this one).
    let before = seed_beam(
        mesh.clone(),
        Formulation::Linear,
        cuts.setup_at(&mesh, t_a - dt).unwrap(),
    )
    .unwrap();
    let model_a = before.update_cut(setup_a.clone()).unwrap().0;
    // The same model built whole: it keeps no element contributions, so its
    // update integrates the changed elements' old blocks again.
    let built_a = seed_beam(mesh.clone(), Formulation::Linear, setup_a).unwrap();
    let opts = DynamicOptions {
        dt,
        ..DynamicOptions::default()
    };
    let mut nm = Newmark::new(&model_a, Cholesky::new(&model_a.pattern).unwrap(), opts).unwrap();
    nm.initialise_acceleration().unwrap();
    for _ in 0..3 {
        nm.step().unwrap();
    }
    let state = nm.state.clone();
    let (model_b, stats) = model_a.update_cut(setup_b.clone()).unwrap();
    let (_, projection) = map_state_reported_with(&model_a, &model_b, &state, par);
    println!("projection: {projection:?}");
    let changed: Vec<usize> = (0..mesh.n_elements())
        .filter(|&e| {
            !xfem_cut::model::same_element_model(
                &mesh,
                model_a.cut.as_ref(),
                model_b.cut.as_ref(),
                e,
            )
        })
        .collect();
    let points: usize = changed
        .iter()
        .map(|&e| {
            let ev = model_b.element_evaluator(e);
            let mut p = Vec::new();
            model_b.field_points_into(e, &ev, &mut p);
            p.len()
        })
        .sum();
    println!(
        "{} {} elements, {} free DOFs, {} tip nodes: {} elements integrated again ({} points, {:.0} an element)",
        mesh.n_elements(),
        if tet10 { "Tet10" } else { "Tet4" },
        model_b.n_free,
        model_b.cut.as_ref().map_or(0, |c| c.n_tip()),
        stats.changed_elements,
        points,
        points as f64 / changed.len().max(1) as f64
    );
    let setup = median(
        || {
            std::hint::black_box(cuts.setup_at(&mesh, t_b).unwrap());
        },
        reps,
    );
    let update = median(
        || {
            std::hint::black_box(
                model_a
                    .update_cut_mapped_with(setup_b.clone(), par)
                    .unwrap(),
            );
        },
        reps,
    );
    let update_built = median(
        || {
            std::hint::black_box(
                built_a
                    .update_cut_mapped_with(setup_b.clone(), par)
                    .unwrap(),
            );
        },
        reps,
    );
    let map = median(
        || {
            std::hint::black_box(map_state_reported_with(&model_a, &model_b, &state, par));
        },
        reps,
    );
    // The event as a sweep runs it: the update takes the projection's
    // integrals of the tip elements on its way (one pass over their points).
    let fused = median(
        || {
            let (m, _, _, fits) = model_a
                .update_cut_fitted_with(setup_b.clone(), &state, par)
                .unwrap();
            std::hint::black_box(map_state_fitted_with(&model_a, &m, &state, &fits, par));
        },
        reps,
    );
    let (m, _, _, fits) = model_a
        .update_cut_fitted_with(setup_b.clone(), &state, par)
        .unwrap();
    let fitted = map_state_fitted_with(&model_a, &m, &state, &fits, par).0;
    let fused_map = median(
        || {
            std::hint::black_box(map_state_fitted_with(&model_a, &m, &state, &fits, par));
        },
        reps,
    );
    let separate = map_state_reported_with(&model_a, &model_b, &state, par).0;
    let scale = separate.d.iter().fold(0.0f64, |s, x| s.max(x.abs()));
    let differ = fitted
        .d
        .iter()
        .zip(&separate.d)
        .fold(0.0f64, |s, (x, y)| s.max((x - y).abs()));
    println!(
        "update with the projection's integrals + projection: {fused:.2} ms (the projection {fused_map:.2} ms; {} elements' integrals taken by the update; mapped d differs from the separate projection by {:.1e} of its largest)",
        fits.len(),
        differ / scale
    );
    let step = median(
        || {
            std::hint::black_box(nm.step().unwrap());
        },
        reps,
    );
    println!(
        "{threads} thread(s): set-up {setup:.2} ms | model update {update:.2} ms (from a built model, old blocks integrated again: {update_built:.2} ms) | state map (projection) {map:.2} ms | a linear step {step:.3} ms"
    );
}
