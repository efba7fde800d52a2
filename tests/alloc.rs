//! The time step allocates nothing after the first, and does a pinned amount
//! of work: a counting global allocator (this binary's own) around
//! Newmark steps, linear and corotational, cut and uncut, lumped and
//! consistent mass, direct and PCG.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::Path;
use xfem_cut::dynamics::{
    DynamicOptions, LinearSolver, MassKind, Newmark, StepReport, DEFAULT_LAGGED,
};
use xfem_cut::model::{Formulation, Model};
use xfem_cut::scene::{Analysis, Scene};
use xfem_cut::solve::Cholesky;

/// Counts the allocations (alloc, alloc_zeroed, realloc) of the calling thread.
struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn count() {
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> u64 {
    ALLOCATIONS.with(|c| c.get())
}

/// A shipped case at level 0 with `formulation`, its model and dynamic options.
fn case(file: &str, formulation: &str) -> (Model, DynamicOptions) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("cases")
        .join(file);
    let text = std::fs::read_to_string(&path).unwrap();
    let text = text.replace(
        "formulation = \"corotational\"",
        &format!("formulation = \"{formulation}\""),
    );
    let scene = Scene::parse(&text, &path).unwrap();
    let (model, _plan) = scene.build(scene.mesh(0).unwrap()).unwrap();
    let Analysis::Dynamic { options, .. } = scene.analysis else {
        panic!("{file} is a dynamic case")
    };
    (model, options)
}

/// Runs `steps` steps after a first one; returns the allocations counted
/// over them and each step's report.
fn run(model: &Model, options: DynamicOptions, steps: usize) -> (u64, Vec<StepReport>) {
    let chol = Cholesky::new(&model.pattern).unwrap();
    let mut nm = Newmark::new(model, chol, options).unwrap();
    nm.initialise_acceleration().unwrap();
    let mut reports = vec![nm.step().unwrap()];
    reports.reserve(steps);
    let before = allocations();
    for _ in 0..steps {
        let r = nm.step().unwrap();
        reports.push(r);
    }
    (allocations() - before, reports)
}

fn iterations(reports: &[StepReport]) -> Vec<usize> {
    reports.iter().map(|r| r.iterations).collect()
}

#[test]
fn the_counter_counts() {
    let before = allocations();
    let v = std::hint::black_box(vec![1u8; 10]);
    assert_eq!(allocations() - before, 1);
    drop(v);
}

#[test]
fn a_linear_step_allocates_nothing_and_factorises_once() {
    for file in ["bend_dynamic.toml", "bend_dynamic_uncut.toml"] {
        for mass in [MassKind::Lumped, MassKind::Consistent] {
            let (model, options) = case(file, "linear");
            let options = DynamicOptions { mass, ..options };
            let (allocated, reports) = run(&model, options, 20);
            assert_eq!(allocated, 0, "{file} {mass:?}: {allocated} allocations");
            // The constant K_eff is factorised in the first step only; each
            // step is one solve, checked by the residual at the end.
            let factorisations: Vec<usize> = reports.iter().map(|r| r.factorisations).collect();
            assert_eq!(factorisations[0], 1, "{file} {mass:?}");
            assert!(
                factorisations[1..].iter().all(|&f| f == 0),
                "{file} {mass:?}"
            );
            assert!(reports.iter().all(|r| r.iterations == 1), "{file} {mass:?}");
        }
    }
}

#[test]
fn a_corotational_step_allocates_nothing_and_factorises_once_per_iteration() {
    for file in ["bend_dynamic.toml", "bend_dynamic_uncut.toml"] {
        for mass in [MassKind::Lumped, MassKind::Consistent] {
            let (model, options) = case(file, "corotational");
            assert_eq!(model.formulation, Formulation::Corotational);
            let options = DynamicOptions {
                mass,
                linear_solver: LinearSolver::Direct,
                ..options
            };
            let (allocated, reports) = run(&model, options, 20);
            assert_eq!(allocated, 0, "{file} {mass:?}: {allocated} allocations");
            for (k, r) in reports.iter().enumerate() {
                assert_eq!(r.factorisations, r.iterations, "{file} {mass:?} step {k}");
                assert!(r.residual <= options.tolerance, "{file} {mass:?} step {k}");
            }
            println!(
                "{file} {mass:?}: Newton iterations {:?}",
                iterations(&reports)
            );
            // The scenes' default: modified Newton on a lagged factor.
            let lagged = DynamicOptions {
                linear_solver: DEFAULT_LAGGED,
                ..options
            };
            let (allocated, reports) = run(&model, lagged, 20);
            assert_eq!(
                allocated, 0,
                "{file} {mass:?} lagged: {allocated} allocations"
            );
            assert!(reports.iter().all(|r| r.residual <= options.tolerance));
            let newton: usize = reports.iter().map(|r| r.iterations).sum();
            let factorisations: usize = reports.iter().map(|r| r.factorisations).sum();
            println!("{file} {mass:?} lagged: {newton} Newton iterations, {factorisations} factorisations");
            assert!(2 * factorisations < newton, "{factorisations} of {newton}");
        }
    }
}

#[test]
fn a_pcg_step_allocates_nothing() {
    for warped in [false, true] {
        pcg_step_allocates_nothing(warped);
    }
}

fn pcg_step_allocates_nothing(warped: bool) {
    let (model, options) = case("bend_dynamic.toml", "corotational");
    let (tolerance, max_cg) = (1e-8, 25);
    let options = DynamicOptions {
        linear_solver: if warped {
            LinearSolver::WarpedPcg { tolerance, max_cg }
        } else {
            LinearSolver::Pcg { tolerance, max_cg }
        },
        ..options
    };
    let (allocated, reports) = run(&model, options, 20);
    assert_eq!(allocated, 0, "{allocated} allocations");
    let cg: usize = reports.iter().map(|r| r.cg_iterations).sum();
    let factorisations: usize = reports.iter().map(|r| r.factorisations).sum();
    let newton: usize = reports.iter().map(|r| r.iterations).sum();
    println!(
        "PCG (warped: {warped}): {newton} Newton, {cg} CG iterations, {factorisations} factorisations in 21 steps"
    );
    // CG replaces most factorisations.
    assert!(
        factorisations < newton,
        "{factorisations} factorisations, {newton} iterations"
    );
    assert!(cg > 0);
}

#[test]
fn a_bordered_linear_step_after_a_cut_event_allocates_nothing() {
    use xfem_cut::blade::{map_state, same_setup};
    use xfem_cut::dynamics::LinearFactor;
    use xfem_cut::study::fixtures::{beam_mesh, seed_beam, seed_blade};
    let mesh = beam_mesh([3, 6, 10], false);
    let cuts = seed_blade(0.0, 1.0);
    let options = DynamicOptions {
        dt: 0.005,
        ..DynamicOptions::default()
    };
    let setup_a = cuts.setup_at(&mesh, 0.5).unwrap();
    let model_a = seed_beam(mesh.clone(), Formulation::Linear, setup_a.clone()).unwrap();
    let mut nm = Newmark::new(&model_a, Cholesky::new(&model_a.pattern).unwrap(), options).unwrap();
    nm.initialise_acceleration().unwrap();
    for _ in 0..3 {
        nm.step().unwrap();
    }
    let mut t = 0.5;
    let setup_b = loop {
        t += options.dt;
        let s = cuts.setup_at(&mesh, t).unwrap();
        if !same_setup(setup_a.as_ref(), s.as_ref()) {
            break s;
        }
    };
    let (model_b, stats) = model_a.update_cut(setup_b).unwrap();
    assert_eq!(stats.dropped_equations, 0);
    assert!(stats.new_equations > 0);
    let state = map_state(&model_a, &model_b, &nm.state);
    let factor: LinearFactor = nm.into_factor();
    assert!(factor.values.is_some());
    let mut nb = Newmark::on_factor(&model_b, factor, options).unwrap();
    nb.state = state;
    // The first step builds the border on the old factor, no factorisation.
    let first = nb.step().unwrap();
    assert_eq!(first.factorisations, 0);
    let border = nb.border().expect("bordered");
    let before = allocations();
    for _ in 0..20 {
        let r = nb.step().unwrap();
        assert_eq!((r.iterations, r.factorisations), (1, 0));
    }
    let allocated = allocations() - before;
    println!("border {border}: {allocated} allocations in 20 steps");
    assert_eq!(allocated, 0, "{allocated} allocations");
    assert_eq!(nb.symbolic_factorisations(), 0);
}
