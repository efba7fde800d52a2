#![allow(clippy::needless_range_loop)]
//! Criterion benches: precompute and one time step, linear and corotational,
//! Tet4 and Tet10; a step as a shipped scene runs it (Newton to its
//! tolerance) with each linear solver, at 1 and 2 threads; the assembly at 1
//! and 2 threads against one pass over the element data (the memory floor).
//!
//! Short runs on a shared machine: `cargo bench --bench step -- --warm-up-time 1 --measurement-time 2`.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use std::hint::black_box;
use std::path::Path;
use std::time::{Duration, Instant};
use xfem_cut::assembly::{
    element_data_pass, equation_shapes, evaluate, Request, Rotations, Workspace,
};
use xfem_cut::dynamics::{DynamicOptions, LinearSolver, Newmark, DEFAULT_LAGGED};
use xfem_cut::mesh::TetMesh;
use xfem_cut::model::{Formulation, Model};
use xfem_cut::scene::{Analysis, Scene};
use xfem_cut::solve::{Cholesky, Parallelism};
use xfem_cut::study::fixtures::{beam_mesh, seed_beam};

/// The allocator of the `xfem-cut` binary, so that these times are the CLI's.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// The seed's beam, bottom clamped, gravity in +x, with mass.
fn model(mesh: TetMesh, formulation: Formulation) -> Model {
    seed_beam(mesh, formulation, None).unwrap()
}

fn chol_new(m: &Model) -> Cholesky {
    Cholesky::new(&m.pattern).unwrap()
}

fn benches(c: &mut Criterion) {
    let sizes = [
        ("1k", [3, 6, 10], false),
        ("10k", [6, 12, 24], false),
        ("1k", [3, 6, 10], true),
    ];
    let mut g = c.benchmark_group("precompute");
    g.sample_size(10);
    for (label, div, tet10) in sizes {
        let kind = if tet10 { "tet10" } else { "tet4" };
        g.bench_function(
            BenchmarkId::new(format!("model+symbolic/{kind}"), label),
            |b| {
                b.iter(|| {
                    let m = model(beam_mesh(div, tet10), Formulation::Corotational);
                    let chol = Cholesky::new(&m.pattern).unwrap();
                    black_box((m.n_free, chol.factor_nnz()))
                })
            },
        );
    }
    g.finish();

    let mut g = c.benchmark_group("step");
    g.sample_size(10);
    for (label, div, tet10) in sizes {
        let kind = if tet10 { "tet10" } else { "tet4" };
        for formulation in [Formulation::Linear, Formulation::Corotational] {
            let m = model(beam_mesh(div, tet10), formulation);
            let name = format!(
                "{}/{kind}/{}tets",
                if formulation == Formulation::Linear {
                    "linear"
                } else {
                    "corotational"
                },
                m.mesh.n_elements()
            );
            let solvers: &[(&str, LinearSolver)] = if formulation == Formulation::Linear {
                &[("", LinearSolver::Direct)]
            } else {
                &[
                    ("/direct", LinearSolver::Direct),
                    (
                        "/pcg",
                        LinearSolver::Pcg {
                            tolerance: 1e-8,
                            max_cg: 25,
                        },
                    ),
                ]
            };
            for (solver_name, solver) in solvers {
                let opts = DynamicOptions {
                    dt: 0.01,
                    steps: 1,
                    max_iterations: 1,
                    linear_solver: *solver,
                    ..DynamicOptions::default()
                };
                let mut nm = Newmark::new(&m, chol_new(&m), opts).unwrap();
                nm.step().unwrap();
                g.bench_function(
                    BenchmarkId::new(format!("{name}{solver_name}"), label),
                    |b| b.iter(|| black_box(nm.step().unwrap())),
                );
            }
        }
        // The assembly alone (rotations + forces + tangent) for the corotational step.
        let m = model(beam_mesh(div, tet10), Formulation::Corotational);
        let d = vec![1e-3; m.n_dofs()];
        let mut rot = Rotations::identity(&m);
        let mut ws = Workspace::new(&m);
        let mut f = vec![0.0; m.n_dofs()];
        let mut k = vec![0.0; m.pattern.nnz()];
        g.bench_function(
            BenchmarkId::new(
                format!("corotational-assembly/{kind}/{}tets", m.mesh.n_elements()),
                label,
            ),
            |b| {
                b.iter(|| {
                    black_box(evaluate(
                        &m,
                        &d,
                        &mut rot,
                        &mut ws,
                        Request {
                            forces: Some(&mut f),
                            tangent: Some(&mut k),
                            update_rotations: true,
                            exact_tangent: false,
                        },
                    ))
                })
            },
        );
    }
    g.finish();
}

/// The assembly (rotations, forces, exact tangent) at 1 and 2 threads, and
/// the element-data pass, on the 10k Tet4 and 1k Tet10 seed beams.
fn threads_and_floor(c: &mut Criterion) {
    let mut g = c.benchmark_group("assembly-threads");
    g.sample_size(10);
    for (label, div, tet10) in [("10k", [6, 12, 24], false), ("1k", [3, 6, 10], true)] {
        let kind = if tet10 { "tet10" } else { "tet4" };
        let m = model(beam_mesh(div, tet10), Formulation::Corotational);
        let d: Vec<f64> = (0..m.n_dofs())
            .map(|i| 1e-3 * (0.37 * i as f64).sin())
            .collect();
        let mut f = vec![0.0; m.n_dofs()];
        let mut k = vec![0.0; m.pattern.nnz()];
        for threads in [1, 2] {
            let mut ws = Workspace::with_parallelism(&m, Parallelism::threads(threads));
            let mut rot = Rotations::identity(&m);
            g.bench_function(
                BenchmarkId::new(format!("exact/{kind}/{threads}threads"), label),
                |b| {
                    b.iter(|| {
                        black_box(evaluate(
                            &m,
                            &d,
                            &mut rot,
                            &mut ws,
                            Request {
                                forces: Some(&mut f),
                                tangent: Some(&mut k),
                                update_rotations: true,
                                exact_tangent: true,
                            },
                        ))
                    })
                },
            );
        }
        g.bench_function(
            BenchmarkId::new(format!("element-data-pass/{kind}"), label),
            |b| {
                b.iter(|| {
                    f.fill(0.0);
                    k.fill(0.0);
                    black_box(element_data_pass(&m, &d, &mut f, &mut k))
                })
            },
        );
    }
    g.finish();
}

/// A step of `bend_dynamic` at level `level` as the scene runs it (Newton
/// to its tolerance 1e-8, exact tangent, damping), timed from the state
/// after 25 steps (mid-ramp, bending), restored before every step: the
/// refactorising Newton, CG on the warped factor, modified Newton on a
/// factor lagged over k = 1, 5, 20 steps; 1 and 2 threads.
fn scene_step(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/bend_dynamic.toml");
    let scene = Scene::load(&path).unwrap();
    let Analysis::Dynamic { options, .. } = scene.analysis else {
        panic!("dynamic")
    };
    let mut g = c.benchmark_group("scene-step");
    g.sample_size(10);
    for level in [0, 1] {
        let (m, _) = scene.build(scene.mesh(level).unwrap()).unwrap();
        let lagged = |every| LinearSolver::Lagged {
            every,
            refactor_after: 8,
            max_rate: 1.0,
            anderson: 0,
        };
        let modes = [
            ("direct", LinearSolver::Direct, 1),
            ("direct", LinearSolver::Direct, 2),
            (
                "warped-pcg",
                LinearSolver::WarpedPcg {
                    tolerance: 1e-10,
                    max_cg: 25,
                },
                1,
            ),
            ("lagged-1", lagged(1), 1),
            ("lagged-5", lagged(5), 1),
            ("lagged-5", lagged(5), 2),
            ("lagged-20", lagged(20), 1),
            ("lagged-default", DEFAULT_LAGGED, 1),
        ];
        for (name, linear_solver, threads) in modes {
            let par = Parallelism::threads(threads);
            let chol =
                Cholesky::fill_reducing(&m.pattern, Some(&equation_shapes(&m)), par).unwrap();
            let opts = DynamicOptions {
                linear_solver,
                ..options
            };
            let mut nm = Newmark::new(&m, chol, opts).unwrap();
            nm.set_parallelism(par);
            nm.initialise_acceleration().unwrap();
            for _ in 0..25 {
                nm.step().unwrap();
            }
            let saved = nm.state.clone();
            g.bench_function(
                BenchmarkId::new(
                    format!("bend_dynamic-L{level}/{name}/{threads}threads"),
                    m.n_free,
                ),
                |b| {
                    b.iter_custom(|iters| {
                        let mut total = Duration::ZERO;
                        for _ in 0..iters {
                            nm.state.clone_from(&saved);
                            let t = Instant::now();
                            black_box(nm.step().unwrap());
                            total += t.elapsed();
                        }
                        total
                    })
                },
            );
        }
    }
    g.finish();
}

/// A step of `bend_dynamic` averaged over the scene's first 100 steps as
/// it runs them (the 0.5 s ramp and 0.5 s after it; Newton to 1e-8, exact
/// tangent, damping; one thread), from a fresh integrator each sample: the
/// refactorising Newton against the default lagged factor
/// ([`DEFAULT_LAGGED`]), whose factor ages over the run as it does in a
/// scene. Criterion's figure is the time per step.
fn scene_run(c: &mut Criterion) {
    const STEPS: u32 = 100;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/bend_dynamic.toml");
    let scene = Scene::load(&path).unwrap();
    let Analysis::Dynamic { options, .. } = scene.analysis else {
        panic!("dynamic")
    };
    let mut g = c.benchmark_group("scene-run");
    g.sample_size(10);
    for level in [0, 1] {
        let (m, _) = scene.build(scene.mesh(level).unwrap()).unwrap();
        let blocks = equation_shapes(&m);
        for (name, linear_solver) in [
            ("direct", LinearSolver::Direct),
            ("lagged-default", DEFAULT_LAGGED),
        ] {
            let opts = DynamicOptions {
                linear_solver,
                ..options
            };
            g.bench_function(
                BenchmarkId::new(format!("bend_dynamic-L{level}/{name}"), m.n_free),
                |b| {
                    b.iter_custom(|iters| {
                        let mut total = Duration::ZERO;
                        for _ in 0..iters {
                            let chol = Cholesky::fill_reducing(
                                &m.pattern,
                                Some(&blocks),
                                Parallelism::SEQUENTIAL,
                            )
                            .unwrap();
                            let mut nm = Newmark::new(&m, chol, opts).unwrap();
                            nm.initialise_acceleration().unwrap();
                            let t = Instant::now();
                            for _ in 0..STEPS {
                                black_box(nm.step().unwrap());
                            }
                            total += t.elapsed();
                        }
                        total / STEPS
                    })
                },
            );
        }
    }
    g.finish();
}

criterion_group!(step, benches, threads_and_floor, scene_step, scene_run);
criterion_main!(step);
