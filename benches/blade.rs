//! Criterion benches of progressive cuts: one cut event against a step
//! during the sweep and a step of the uncut beam, Tet4 1k/10k and Tet10 1k,
//! linear and corotational (its steps Newton to the tolerance on the lagged
//! factor a case file defaults to, `DEFAULT_LAGGED`, since the eighth
//! session; before, refactorising every iteration).
//!
//! - `event_update`: what an event costs today: the set-up at the new time,
//!   [`Model::update_cut`], the state mapped, the symbolic factorisation
//!   (the pattern grows at these events), then the step after it with its
//!   numeric refactorisation; `event_rebuild`: the same with the model built
//!   again (the previous code path).
//! - `event_update_bordered` (linear): what a linear event costs in
//!   `run_dynamic` now: the set-up, the model update, the state mapped, and
//!   the step after it on the previous factor ([`Newmark::on_factor`]: the
//!   border's set-up on it instead of symbolic + numeric factorisation).
//! - Its phases: `setup`, `update` / `build` (the model), `symbolic`,
//!   `first_step` (integrator, numeric factorisation and the step's solve).
//!
//! - Linear: `event_refactor` against `event_bordered` (the new system
//!   solved by refactorisation or by [`BorderedSolve`] on the old factor),
//!   and one solve of each.
//!
//! - Tip front (the default): `tip_event` (set-up, model update with the
//!   projection's integrals of the tip elements as `run_dynamic` takes them,
//!   state mapped and projected, the step after it: on the carried
//!   factor's symbolic analysis where the pattern is unchanged, else a new
//!   one; linear: with its numeric factorisation; corotational: iterating
//!   on the carried lagged factor where every equation kept its number,
//!   refactorised where its rate asks, as `run_dynamic` does) and its
//!   costliest phases as separate calls, `tip_update` and `tip_map_state`
//!   (the projection evaluating every element itself; linear only: the same
//!   for both formulations), `tip_update_fitted` and `tip_map_state_fitted`
//!   (the two as the sweep runs them), beside `tip_step_sweep` (a step on
//!   the tip-cut beam), and `tip_event_2threads` (the event on two
//!   threads). `examples/tip_event.rs` splits it further.
//!
//! Short runs: `cargo bench --bench blade -- --warm-up-time 1 --measurement-time 3`.

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion};
use std::hint::black_box;
use xfem_cut::blade::{
    map_state, map_state_fitted_with, same_setup, stiffness_plus_mass, sweep_factor, CutSet,
};
use xfem_cut::cut::CutSetup;
use xfem_cut::dynamics::{
    DynamicOptions, LinearFactor, LinearForces, Newmark, State, DEFAULT_LAGGED,
};
use xfem_cut::mesh::TetMesh;
use xfem_cut::model::{Formulation, Model};
use xfem_cut::solve::{BorderedSolve, Cholesky, Parallelism};
use xfem_cut::study::fixtures::{beam_mesh, seed_beam, seed_blade};

/// The allocator of the `xfem-cut` binary, so that these times are the CLI's.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// The seed's beam on `mesh`, bottom clamped, gravity in +x, with mass.
fn model(mesh: &TetMesh, cut: Option<CutSetup>, formulation: Formulation) -> Model {
    seed_beam(mesh.clone(), formulation, cut).unwrap()
}

/// A blade opening the seed's cut (x from 0 to 0.015 at z = 0.1) during [0, 1] s.
fn cuts() -> CutSet {
    seed_blade(0.0, 1.0)
}

/// An integrator on `model` from rest, three steps on (its factor made).
fn settled(model: &Model, opts: DynamicOptions) -> Newmark<'_> {
    let mut nm = Newmark::new(model, Cholesky::new(&model.pattern).unwrap(), opts).unwrap();
    nm.initialise_acceleration().unwrap();
    for _ in 0..3 {
        nm.step().unwrap();
    }
    nm
}

/// The step after an event on `model` from the mapped `state` (integrator,
/// numeric factorisation, the step), on the factorisation `chol`.
fn first_step(model: &Model, chol: Cholesky, state: State, opts: DynamicOptions) {
    let mut nb = Newmark::new(model, chol, opts).unwrap();
    nb.state = state;
    black_box(nb.step().unwrap());
}

/// The carried factor `old` where `model`'s pattern is the one it was
/// made for, else a symbolic factorisation of the new pattern (what a
/// sweep does at an event).
fn symbolic_for(old: Cholesky, model: &Model) -> Cholesky {
    let p = old.pattern();
    if p.col_ptr == model.pattern.col_ptr && p.row_idx == model.pattern.row_idx {
        old
    } else {
        sweep_factor(model).unwrap()
    }
}

/// The linear system after the event solved two ways, each from the set-up
/// at the new time: `event_refactor` (model update, K + cM assembled,
/// symbolic and numeric factorisation, one solve) against `event_bordered`
/// (model update, K + cM assembled, [`BorderedSolve`] on the old factor,
/// one solve); and one solve of each (`solve_factor`, `solve_bordered`).
fn bordered(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    name: &str,
    model_a: &Model,
    updated: &Model,
    cuts: &CutSet,
    mesh: &TetMesh,
    t_b: f64,
) {
    // c = 1/(β dt²) of the benches' 5 ms step.
    let c = 1.0 / (0.25 * 0.005f64.powi(2));
    let a_old = stiffness_plus_mass(model_a, c);
    let mut old = Cholesky::new(&model_a.pattern).unwrap();
    old.factorize(&a_old).unwrap();
    let b: Vec<f64> = (0..updated.n_free)
        .map(|i| ((i as f64) * 0.71).cos())
        .collect();
    let a_new = stiffness_plus_mass(updated, c);
    let mut direct = Cholesky::new(&updated.pattern).unwrap();
    direct.factorize(&a_new).unwrap();
    let mut bs = BorderedSolve::new(
        &mut old,
        &model_a.pattern,
        &a_old,
        &updated.pattern,
        &a_new,
        1e-13,
    )
    .unwrap();
    let (mut x, mut y) = (b.clone(), b.clone());
    bs.solve_in_place(&mut old, &mut x);
    direct.solve_in_place(&mut y);
    let diff = x
        .iter()
        .zip(&y)
        .fold(0.0f64, |m, (p, q)| m.max((p - q).abs()))
        / y.iter().fold(0.0f64, |m, q| m.max(q.abs()));
    eprintln!(
        "{name}: border {} ({} solves on the old factor), bordered vs refactorised {diff:.1e}",
        bs.border(),
        bs.event_solves()
    );
    group.bench_function(BenchmarkId::new("event_refactor", name), |bn| {
        bn.iter(|| {
            let s = cuts.setup_at(mesh, t_b).unwrap();
            let (m, _) = model_a.update_cut(s).unwrap();
            let a = stiffness_plus_mass(&m, c);
            let mut chol = Cholesky::new(&m.pattern).unwrap();
            chol.factorize(&a).unwrap();
            let mut x = b.clone();
            chol.solve_in_place(&mut x);
            black_box(x)
        })
    });
    group.bench_function(BenchmarkId::new("event_bordered", name), |bn| {
        bn.iter(|| {
            let s = cuts.setup_at(mesh, t_b).unwrap();
            let (m, _) = model_a.update_cut(s).unwrap();
            let a = stiffness_plus_mass(&m, c);
            let mut bs =
                BorderedSolve::new(&mut old, &model_a.pattern, &a_old, &m.pattern, &a, 1e-13)
                    .unwrap();
            let mut x = b.clone();
            bs.solve_in_place(&mut old, &mut x);
            black_box(x)
        })
    });
    group.bench_function(BenchmarkId::new("solve_factor", name), |bn| {
        bn.iter(|| {
            let mut x = b.clone();
            direct.solve_in_place(&mut x);
            black_box(x)
        })
    });
    group.bench_function(BenchmarkId::new("solve_bordered", name), |bn| {
        bn.iter(|| {
            let mut x = b.clone();
            bs.solve_in_place(&mut old, &mut x);
            black_box(x)
        })
    });
}

fn benches(c: &mut Criterion) {
    // The step a case file runs: the lagged factor (a linear scene solves
    // once on its factor whatever this says).
    let opts = DynamicOptions {
        dt: 0.005,
        linear_solver: DEFAULT_LAGGED,
        ..DynamicOptions::default()
    };
    let mut group = c.benchmark_group("blade");
    group.sample_size(10);
    for (size, div, tet10) in [
        ("tet4_1k", [3, 6, 10], false),
        ("tet4_10k", [6, 12, 24], false),
        ("tet10_1k", [3, 6, 10], true),
    ] {
        let mesh = beam_mesh(div, tet10);
        let cuts = cuts();
        // The set-up half-way, and the time of the next event after it.
        let t_a = 0.5;
        let setup_a = cuts.setup_at(&mesh, t_a).unwrap();
        let mut t_b = t_a;
        let setup_b = loop {
            t_b += opts.dt;
            let s = cuts.setup_at(&mesh, t_b).unwrap();
            if !same_setup(setup_a.as_ref(), s.as_ref()) || t_b > 1.0 {
                break s;
            }
        };
        for formulation in [Formulation::Linear, Formulation::Corotational] {
            let name = format!("{size}_{formulation:?}").to_lowercase();
            let uncut = model(&mesh, None, formulation);
            let mut nm = settled(&uncut, opts);
            group.bench_function(BenchmarkId::new("step_uncut", &name), |b| {
                b.iter(|| black_box(nm.step().unwrap()))
            });
            let model_a = model(&mesh, setup_a.clone(), formulation);
            let mut nm = settled(&model_a, opts);
            let state_a = nm.state.clone();
            group.bench_function(BenchmarkId::new("step_sweep", &name), |b| {
                b.iter(|| black_box(nm.step().unwrap()))
            });
            let (updated, stats) = model_a.update_cut(setup_b.clone()).unwrap();
            let pattern_changed = updated.pattern.col_ptr != model_a.pattern.col_ptr
                || updated.pattern.row_idx != model_a.pattern.row_idx;
            eprintln!(
                "{name}: event at t = {t_b:.3}: {} of {} elements integrated again, {} equations added ({} → {}), pattern changed: {pattern_changed}",
                stats.changed_elements,
                mesh.n_elements(),
                stats.new_equations,
                model_a.n_free,
                updated.n_free
            );
            let symbolic = |m: &Model| sweep_factor(m).unwrap();
            group.bench_function(BenchmarkId::new("event_update", &name), |b| {
                b.iter(|| {
                    let s = cuts.setup_at(&mesh, t_b).unwrap();
                    let (model_b, _) = model_a.update_cut(s).unwrap();
                    let mapped = map_state(&model_a, &model_b, &state_a);
                    first_step(&model_b, symbolic(&model_b), mapped, opts);
                })
            });
            if formulation == Formulation::Linear {
                // The previous integrator's factor and stiffness, made outside the timing.
                let factor = || -> (LinearFactor, Option<LinearForces>) {
                    let mut nm =
                        Newmark::new(&model_a, Cholesky::new(&model_a.pattern).unwrap(), opts)
                            .unwrap();
                    nm.state = state_a.clone();
                    nm.step().unwrap();
                    let forces = nm.take_linear_forces();
                    (nm.into_factor(), forces)
                };
                // As the blade driver does it: the stiffness carried over the event.
                group.bench_function(BenchmarkId::new("event_update_bordered", &name), |b| {
                    b.iter_batched(
                        factor,
                        |(f, forces)| {
                            let s = cuts.setup_at(&mesh, t_b).unwrap();
                            let (model_b, _, update) = model_a.update_cut_mapped(s).unwrap();
                            let mapped = map_state(&model_a, &model_b, &state_a);
                            let mut nb = Newmark::on_factor(&model_b, f, opts).unwrap();
                            if let Some(forces) = forces {
                                nb.set_linear_forces(forces.updated(&model_a, &model_b, &update));
                            }
                            nb.state = mapped;
                            black_box(nb.step().unwrap());
                            assert!(nb.border().is_some());
                        },
                        BatchSize::LargeInput,
                    )
                });
            }
            group.bench_function(BenchmarkId::new("event_rebuild", &name), |b| {
                b.iter(|| {
                    let s = cuts.setup_at(&mesh, t_b).unwrap();
                    let model_b = model(&mesh, s, formulation);
                    let mapped = map_state(&model_a, &model_b, &state_a);
                    first_step(&model_b, symbolic(&model_b), mapped, opts);
                })
            });
            group.bench_function(BenchmarkId::new("setup", &name), |b| {
                b.iter(|| black_box(cuts.setup_at(&mesh, t_b).unwrap()))
            });
            group.bench_function(BenchmarkId::new("update", &name), |b| {
                b.iter(|| black_box(model_a.update_cut(setup_b.clone()).unwrap()))
            });
            group.bench_function(BenchmarkId::new("build", &name), |b| {
                b.iter(|| black_box(model(&mesh, setup_b.clone(), formulation)))
            });
            group.bench_function(BenchmarkId::new("symbolic", &name), |b| {
                b.iter(|| black_box(symbolic(&updated)))
            });
            if formulation == Formulation::Linear {
                bordered(&mut group, &name, &model_a, &updated, &cuts, &mesh, t_b);
            }
            let mapped = map_state(&model_a, &updated, &state_a);
            group.bench_function(BenchmarkId::new("first_step", &name), |b| {
                b.iter_batched(
                    || (symbolic(&updated), mapped.clone()),
                    |(chol, state)| first_step(&updated, chol, state, opts),
                    BatchSize::LargeInput,
                )
            });
        }
    }
    // A tip front (the default `front`): it moves with the blade, so every
    // step of the sweep is an event, whose branch functions change on every
    // element holding them (set-up, model update, the state projected by
    // least squares, the step after it on a new factor).
    for (size, div, tet10) in [
        ("tet4_1k", [3, 6, 10], false),
        ("tet4_10k", [6, 12, 24], false),
        ("tet10_1k", [3, 6, 10], true),
    ] {
        let mesh = beam_mesh(div, tet10);
        let cuts = CutSet {
            front: xfem_cut::cut::FrontMode::Tip,
            ..cuts()
        };
        let (t_a, t_b) = (0.5, 0.5 + opts.dt);
        let setup_a = cuts.setup_at(&mesh, t_a).unwrap();
        let setup_b = cuts.setup_at(&mesh, t_b).unwrap();
        for formulation in [Formulation::Linear, Formulation::Corotational] {
            let name = format!("{size}_{formulation:?}").to_lowercase();
            // The model at t_a as a sweep has it: updated from the step before.
            let before = model(
                &mesh,
                cuts.setup_at(&mesh, t_a - opts.dt).unwrap(),
                formulation,
            );
            let model_a = before.update_cut(setup_a.clone()).unwrap().0;
            let mut nm = settled(&model_a, opts);
            let state_a = nm.state.clone();
            let (model_b, stats) = model_a.update_cut(setup_b.clone()).unwrap();
            eprintln!(
                "{name}, tip front: event at t = {t_b:.3}: {} of {} elements integrated again, {} → {} equations, {} tip nodes",
                stats.changed_elements,
                mesh.n_elements(),
                model_a.n_free,
                model_b.n_free,
                model_b.cut.as_ref().map_or(0, |c| c.n_tip())
            );
            // The factor the sweep carries into the event (made outside the
            // timing): its symbolic factorisation serves the new model where
            // the pattern did not change, and a corotational scene's steps
            // after the event iterate on its lagged numeric factor where
            // every equation kept its number, as in `run_dynamic`.
            let carried = || {
                let mut nm =
                    Newmark::new(&model_a, Cholesky::new(&model_a.pattern).unwrap(), opts).unwrap();
                nm.state = state_a.clone();
                nm.step().unwrap();
                nm.into_factor()
            };
            let event = |old: LinearFactor, parallelism: Parallelism| {
                let s = cuts.setup_at(&mesh, t_b).unwrap();
                let (m, _, update, fits) = model_a
                    .update_cut_fitted_with(s, &state_a, parallelism)
                    .unwrap();
                let (mapped, _) = map_state_fitted_with(&model_a, &m, &state_a, &fits, parallelism);
                let lagged = old.lagged.filter(|_| update.keeps_every_equation(m.n_free));
                let factor = LinearFactor {
                    chol: symbolic_for(old.chol, &m),
                    values: None,
                    border: None,
                    lagged,
                };
                let mut nb = Newmark::on_factor(&m, factor, opts).unwrap();
                if parallelism.n_threads() > 1 {
                    nb.set_parallelism(parallelism);
                }
                nb.state = mapped;
                black_box(nb.step().unwrap());
            };
            group.bench_function(BenchmarkId::new("tip_event", &name), |b| {
                b.iter_batched(
                    carried,
                    |old| event(old, Parallelism::SEQUENTIAL),
                    BatchSize::LargeInput,
                )
            });
            // The same event on two threads (`XFEM_THREADS=2`: the changed
            // elements' integration, the projection and the step's element
            // loops side by side).
            let two = Parallelism::threads(2);
            group.bench_function(BenchmarkId::new("tip_event_2threads", &name), |b| {
                b.iter_batched(carried, |old| event(old, two), BatchSize::LargeInput)
            });
            // The phases, once (they do not depend on the formulation).
            if formulation == Formulation::Linear {
                group.bench_function(BenchmarkId::new("tip_update", &name), |b| {
                    b.iter(|| black_box(model_a.update_cut(setup_b.clone()).unwrap()))
                });
                group.bench_function(BenchmarkId::new("tip_map_state", &name), |b| {
                    b.iter(|| black_box(map_state(&model_a, &model_b, &state_a)))
                });
                // As the sweep runs them: the update taking the projection's
                // integrals of the tip elements, and the projection left.
                let seq = Parallelism::SEQUENTIAL;
                group.bench_function(BenchmarkId::new("tip_update_fitted", &name), |b| {
                    b.iter(|| {
                        black_box(
                            model_a
                                .update_cut_fitted_with(setup_b.clone(), &state_a, seq)
                                .unwrap(),
                        )
                    })
                });
                let (fitted_b, _, _, fits) = model_a
                    .update_cut_fitted_with(setup_b.clone(), &state_a, seq)
                    .unwrap();
                group.bench_function(BenchmarkId::new("tip_map_state_fitted", &name), |b| {
                    b.iter(|| {
                        black_box(map_state_fitted_with(
                            &model_a, &fitted_b, &state_a, &fits, seq,
                        ))
                    })
                });
            }
            group.bench_function(BenchmarkId::new("tip_step_sweep", &name), |b| {
                b.iter(|| black_box(nm.step().unwrap()))
            });
        }
    }
    group.finish();
}

criterion_group!(blade_benches, benches);
criterion_main!(blade_benches);
