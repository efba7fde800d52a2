//! The cost of a sweep as a time series: a blade opens the seed's cut during
//! [0.1, 0.6] s on the beam; prints CSV `time,step_seconds,event,event_seconds`
//! (event: a cut event followed the step; event_seconds its own time) and
//! the sweep's summary on stderr; with `--out DIR` also writes
//! `DIR/data/sweep_series.csv` and `DIR/sweep_series.svg` ([`xfem_cut::study::sweep`]).
//! `cargo run --release --example sweep_series -- [NX NY NZ] [linear|corotational] [tet10] [--out reports]`
use xfem_cut::blade::run_dynamic;
use xfem_cut::dynamics::DynamicOptions;
use xfem_cut::model::Formulation;
use xfem_cut::study::fixtures::{beam_mesh, seed_beam, seed_blade};
use xfem_cut::study::sweep;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let div: Vec<usize> = args.iter().map_while(|a| a.parse().ok()).collect();
    let div = if div.len() == 3 {
        [div[0], div[1], div[2]]
    } else {
        [3, 6, 10]
    };
    let formulation = if args.iter().any(|a| a == "corotational") {
        Formulation::Corotational
    } else {
        Formulation::Linear
    };
    let tet10 = args.iter().any(|a| a == "tet10");
    let out = args
        .iter()
        .position(|a| a == "--out")
        .and_then(|k| args.get(k + 1))
        .map(std::path::PathBuf::from);
    let mesh = beam_mesh(div, tet10);
    let cuts = seed_blade(0.1, 0.6);
    let build = |cut| seed_beam(mesh.clone(), formulation, cut);
    let opts = DynamicOptions {
        dt: 0.01,
        steps: 70,
        ..DynamicOptions::default()
    };
    let run = run_dynamic(&cuts, &mesh, &build, opts, |_, _, _| {}).unwrap();
    let rows = sweep::rows(&run.sweep);
    println!("time,step_seconds,event,event_seconds");
    for r in &rows {
        println!(
            "{:.4},{:.6e},{},{:.6e}",
            r.time, r.step_seconds, r.event, r.event_seconds
        );
    }
    let kind = if tet10 { "Tet10" } else { "Tet4" };
    let summary = format!(
        "{} {kind} {formulation:?}: {}",
        mesh.n_elements(),
        run.sweep
    );
    eprintln!("{summary}");
    let sweep_steps: Vec<f64> = rows
        .iter()
        .filter(|r| r.time > 0.1 && r.time <= 0.6 + 1e-9)
        .map(|r| r.step_seconds)
        .collect();
    let after: Vec<f64> = rows
        .iter()
        .filter(|r| r.time > 0.6 + 1e-9)
        .map(|r| r.step_seconds)
        .collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    eprintln!(
        "mean step during the sweep {:.3e} s, after it {:.3e} s (ratio {:.2})",
        mean(&sweep_steps),
        mean(&after),
        mean(&sweep_steps) / mean(&after)
    );
    for e in &run.sweep.events {
        eprintln!(
            "  event after step {} (t = {:.2}): DOFs {} → {}, {} elements integrated again, {:.3e} s (model {:.3e}, symbolic {:.3e})",
            e.step, e.time, e.dofs_before, e.dofs_after, e.changed_elements, e.seconds, e.model_seconds, e.symbolic_seconds
        );
    }
    if let Some(dir) = out {
        std::fs::create_dir_all(dir.join("data")).unwrap();
        sweep::write_csv(&dir.join("data/sweep_series.csv"), &rows).unwrap();
        let title = format!(
            "Sweep cost: {} {kind} {formulation:?}, blade during [0.1, 0.6] s",
            mesh.n_elements()
        );
        sweep::plot(&dir.join("sweep_series.svg"), &title, &rows).unwrap();
    }
}
