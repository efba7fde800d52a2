//! Newton in dynamics: per-step iterations, factorisations and time of a
//! shipped dynamic case with the exact tangent against R K Rᵀ.
//!
//! `cargo run --release --example dynamic_newton -- cases/bend_dynamic.toml 1 100`
//! (case, mesh level, steps).
use std::path::Path;
use std::time::Instant;
use xfem_cut::dynamics::{DynamicOptions, Newmark};
use xfem_cut::scene::{Analysis, Scene};
use xfem_cut::solve::Cholesky;

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
    let steps: usize = args.get(2).map_or(100, |s| s.parse().expect("steps"));
    let scene = Scene::load(Path::new(file)).expect("case loads");
    let (model, _) = scene
        .build(scene.mesh(level).expect("mesh"))
        .expect("model");
    let Analysis::Dynamic { options, .. } = scene.analysis else {
        panic!("{file} is not dynamic")
    };
    println!(
        "{file} level {level}: {} tets, {} free DOFs, {steps} steps, tolerance {:e}",
        model.mesh.n_elements(),
        model.n_free,
        options.tolerance
    );
    println!("tangent     | Newton/step mean max | fact./step | fallbacks | ms/step median max");
    for exact_tangent in [true, false] {
        let options = DynamicOptions {
            exact_tangent,
            ..options
        };
        let chol = Cholesky::new(&model.pattern).expect("symbolic");
        let mut nm = Newmark::new(&model, chol, options).expect("integrator");
        nm.initialise_acceleration().expect("initial acceleration");
        let (mut its, mut facts, mut fallbacks, mut times) = (vec![], 0, 0, vec![]);
        for _ in 0..steps {
            let t = Instant::now();
            let r = nm.step().expect("step");
            times.push(t.elapsed().as_secs_f64() * 1e3);
            its.push(r.iterations);
            facts += r.factorisations;
            fallbacks += r.fallbacks;
        }
        times.sort_by(f64::total_cmp);
        println!(
            "{:11} | {:>9.2} {:>10} | {:>10.2} | {:>9} | {:>9.2} {:>7.2}",
            if exact_tangent { "exact" } else { "R K Rᵀ" },
            its.iter().sum::<usize>() as f64 / steps as f64,
            its.iter().max().unwrap(),
            facts as f64 / steps as f64,
            fallbacks,
            times[steps / 2],
            times[steps - 1]
        );
        if std::env::var_os("XFEM_VERBOSE").is_some() {
            println!("  iterations per step: {its:?}");
        }
    }
}
