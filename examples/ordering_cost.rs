//! What `solve::UPDATE_PAIR_COST` was fitted to: on the seed beam (bottom
//! clamped, gravity, corotational tangent at rest), uncut, with the seed's
//! cut shortened to x = 0.0137 and extended to its elements' faces, or
//! tip-enriched, each candidate of `Cholesky::fill_reducing` (AMD, METIS
//! nested dissection on the shape-function graph and on the equation
//! graph): entries in L, supernodes, update pairs, flops, the estimated cost
//! (flops + UPDATE_PAIR_COST × pairs) and the medians of 60 numeric
//! factorisations and of the solves after them, the candidates taking turns
//! (this machine's speed drifts by tens of per cent within minutes;
//! interleaving keeps the comparison fair); then the candidate
//! `fill_reducing` keeps.
//!
//! `cargo run --release --example ordering_cost -- [NX NY NZ] [tet10] [uncut|extend|tip]`
//! (default: 3 6 10, Tet4, all three cuts).
use nalgebra::{Point3, Vector3};
use std::time::Instant;
use xfem_cut::assembly::{equation_shapes, evaluate, Request, Rotations, Workspace};
use xfem_cut::cut::{setup_cut, CutInput, PlanarPatch, DEFAULT_SNAP};
use xfem_cut::model::Formulation;
use xfem_cut::solve::{Cholesky, Ordering, Parallelism, UPDATE_PAIR_COST};
use xfem_cut::study::fixtures::{beam_mesh, seed_beam};

/// The allocator the `xfem-cut` binary and the benches run with.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let div: Vec<usize> = args.iter().take(3).map_while(|a| a.parse().ok()).collect();
    let div = if div.len() == 3 {
        [div[0], div[1], div[2]]
    } else {
        [3, 6, 10]
    };
    let tet10 = args.iter().any(|a| a == "tet10");
    let fronts: Vec<&str> = ["uncut", "extend", "tip"]
        .into_iter()
        .filter(|f| args.iter().any(|a| a == f))
        .collect();
    let fronts = if fronts.is_empty() {
        vec!["uncut", "extend", "tip"]
    } else {
        fronts
    };
    let seq = Parallelism::SEQUENTIAL;
    for front in fronts {
        let mesh = beam_mesh(div, tet10);
        let patch = PlanarPatch {
            origin: Point3::new(0.0, 0.0, 0.1),
            u: Vector3::new(0.0137, 0.0, 0.0),
            v: Vector3::new(0.0, 0.06, 0.0),
        };
        let cut = match front {
            "extend" => Some(CutInput::extend(&patch, DEFAULT_SNAP)),
            "tip" => Some(CutInput::tip(&patch, DEFAULT_SNAP, None)),
            _ => None,
        }
        .map(|input| setup_cut(&mesh, &[input]).expect("cut set-up"));
        let m = seed_beam(mesh, Formulation::Corotational, cut).expect("model");
        let mut values = vec![0.0; m.pattern.nnz()];
        evaluate(
            &m,
            &vec![0.0; m.n_dofs()],
            &mut Rotations::identity(&m),
            &mut Workspace::new(&m),
            Request {
                forces: None,
                tangent: Some(&mut values),
                update_rotations: true,
                exact_tangent: true,
            },
        );
        let shapes = equation_shapes(&m);
        let kept = Cholesky::fill_reducing(&m.pattern, Some(&shapes), seq).expect("factor");
        println!(
            "\n{} {} ({front}, {} equations): fill_reducing keeps {}",
            m.mesh.n_elements(),
            if tet10 { "Tet10" } else { "Tet4" },
            m.pattern.n,
            kept.describe()
        );
        let orderings = [
            ("AMD", Ordering::Amd),
            (
                "ND shape graph",
                Ordering::nested_dissection(&m.pattern, Some(&shapes)).expect("METIS"),
            ),
            (
                "ND equation graph",
                Ordering::nested_dissection(&m.pattern, None).expect("METIS"),
            ),
        ];
        let mut factors: Vec<(&str, Cholesky, Vec<f64>, Vec<f64>)> = orderings
            .iter()
            .map(|(name, o)| {
                let f = Cholesky::with(&m.pattern, o, seq).expect("factor");
                (*name, f, vec![], vec![])
            })
            .collect();
        let rhs: Vec<f64> = (0..m.pattern.n).map(|i| (i as f64).sin()).collect();
        let mut x = rhs.clone();
        for _ in 0..60 {
            for (_, f, times, solves) in factors.iter_mut() {
                let t = Instant::now();
                f.factorize(&values).expect("SPD tangent");
                times.push(t.elapsed().as_secs_f64() * 1e3);
                x.copy_from_slice(&rhs);
                let t = Instant::now();
                f.solve_in_place(&mut x);
                solves.push(t.elapsed().as_secs_f64() * 1e3);
            }
        }
        for (name, f, times, solves) in factors.iter_mut() {
            solves.sort_by(f64::total_cmp);
            times.sort_by(f64::total_cmp);
            println!(
                "  {name:18}: {:8} entries in L, {:4} supernodes, {:5} update pairs, {:.3e} flops, cost {:.3e} (pairs {:.0} %), numeric {:.3} ms, solve {:.3} ms",
                f.factor_nnz(),
                f.supernodes().unwrap_or(0),
                f.update_pairs().unwrap_or(0),
                f.factor_flops().unwrap_or(f64::NAN),
                f.factor_cost().unwrap_or(f64::NAN),
                100.0 * UPDATE_PAIR_COST * f.update_pairs().unwrap_or(0) as f64
                    / f.factor_cost().unwrap_or(f64::NAN),
                times[times.len() / 2],
                solves[solves.len() / 2]
            );
        }
    }
}
