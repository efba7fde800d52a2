//! The costs behind the bordered solve's rules (`dynamics::border_limit`,
//! `dynamics::refresh_after`): a blade opening the seed's cut on the beam,
//! one factor of K + cM at t = 0.3 and at each later cut event (while no
//! DOF is dropped) the assembly, symbolic and numeric factorisation of the
//! new matrix, the border's set-up on the old factor (grown from the
//! previous one) and one solve directly and bordered; medians of 7.
//! `cargo run --release --example border_costs -- NX NY NZ [tet10]`
use std::time::Instant;
use xfem_cut::blade::{same_setup, stiffness_plus_mass};
use xfem_cut::model::Formulation;
use xfem_cut::solve::{BorderedSolve, Cholesky, BORDER_TOLERANCE};
use xfem_cut::study::fixtures::{beam_mesh, seed_beam, seed_blade};

/// The allocator the `xfem-cut` binary and the benches run with (see
/// `src/main.rs`), so that what this times is what a run pays.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let tet10 = std::env::args().any(|a| a == "tet10");
    let mesh = beam_mesh([args[0], args[1], args[2]], tet10);
    let cuts = seed_blade(0.0, 1.0);
    let c = 1.0 / (0.25 * 0.01f64.powi(2));
    let base_t = 0.3;
    let base = seed_beam(
        mesh.clone(),
        Formulation::Linear,
        cuts.setup_at(&mesh, base_t).unwrap(),
    )
    .unwrap();
    let a0 = stiffness_plus_mass(&base, c);
    let mut chol = Cholesky::new(&base.pattern).unwrap();
    chol.factorize(&a0).unwrap();
    println!(
        "n = {}, nnz(A) = {}, nnz(L) = {}, limit {}",
        base.n_free,
        base.pattern.nnz(),
        chol.factor_nnz(),
        xfem_cut::dynamics::border_limit(100000, base.n_free, chol.factor_nnz())
    );
    let mut model = seed_beam(
        mesh.clone(),
        Formulation::Linear,
        cuts.setup_at(&mesh, base_t).unwrap(),
    )
    .unwrap();
    let mut t = base_t;
    let mut prev: Option<BorderedSolve> = None;
    let med = |f: &mut dyn FnMut()| {
        let mut v: Vec<f64> = (0..7)
            .map(|_| {
                let t0 = Instant::now();
                f();
                t0.elapsed().as_secs_f64()
            })
            .collect();
        v.sort_by(f64::total_cmp);
        v[3] * 1e3
    };
    while t < 1.0 {
        t += 0.01;
        let s = cuts.setup_at(&mesh, t).unwrap();
        if same_setup(model.cut.as_ref(), s.as_ref()) {
            continue;
        }
        let (next, stats) = model.update_cut(s).unwrap();
        if stats.dropped_equations > 0 {
            println!("dropped");
            break;
        }
        let a = stiffness_plus_mass(&next, c);
        let t_assemble = med(&mut || {
            std::hint::black_box(stiffness_plus_mass(&next, c));
        });
        let mut direct = Cholesky::new(&next.pattern).unwrap();
        let t_symbolic = med(&mut || {
            std::hint::black_box(Cholesky::new(&next.pattern).unwrap());
        });
        let t_numeric = med(&mut || {
            direct.factorize(&a).unwrap();
        });
        let mut bs = None;
        let t_border = med(&mut || {
            bs = BorderedSolve::grown(
                prev.as_ref(),
                &mut chol,
                &base.pattern,
                &a0,
                &next.pattern,
                &a,
                BORDER_TOLERANCE,
            );
        });
        let mut bs = bs.unwrap();
        let solved = bs.solved_columns();
        let mut x: Vec<f64> = (0..next.n_free).map(|i| (i as f64).sin()).collect();
        let t_solve = med(&mut || {
            direct.solve_in_place(&mut x);
        });
        let t_bsolve = med(&mut || {
            bs.solve_in_place(&mut chol, &mut x);
        });
        println!(
            "t = {t:.2}: n {} k {} ({} columns, {solved} solved): assemble {t_assemble:.3} ms, symbolic {t_symbolic:.3}, numeric {t_numeric:.3} ({:.1} solves), border set-up {t_border:.3}; solve {t_solve:.4} vs bordered {t_bsolve:.4} (+{:.2} solves; rule: +{:.2}, refresh after {} steps)",
            next.n_free,
            bs.border(),
            bs.event_solves(),
            t_numeric / t_solve,
            (t_bsolve - t_solve) / t_solve,
            (base.n_free * bs.border()) as f64 / chol.factor_nnz() as f64,
            xfem_cut::dynamics::refresh_after(bs.border(), base.n_free, chol.factor_nnz())
        );
        prev = Some(bs);
        model = next;
    }
}
