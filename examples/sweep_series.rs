//! The cost of a sweep as a time series: a blade opens the seed's cut during
//! [0.1, 0.6] s on the beam (uncut before it); prints CSV
//! `time,step_seconds,event,event_seconds` (event: a cut event followed the
//! step; event_seconds its own time) and the sweep's summary on stderr,
//! with its phases (`study::sweep::phases`: the uncut step before the
//! blade enters, the mean step of the sweep with its events, the step
//! after); with `--out DIR` also writes `DIR/data/STEM.csv` and
//! `DIR/STEM.svg` ([`xfem_cut::study::sweep`]), STEM `sweep_series` with
//! `_tip`, `_corotational`, `_tet10`, `_event_travel_D` appended as they apply. The front is
//! extended through the elements it is in, or with `tip` tip-enriched (the
//! default of a case file); corotational steps take the lagged factor a
//! case file defaults to ([`xfem_cut::dynamics::DEFAULT_LAGGED`]). `refactorise` solves the linear steps after
//! events by refactorisation instead of the default bordered solve on the
//! last factor; `border K` sets the border limit; `event_travel=D` gives
//! the blade an `event_travel` of D m (a cut event only once its edge has
//! moved that far: the seed's blade moves 0.3 mm a step).
//! `cargo run --release --example sweep_series -- [NX NY NZ] [linear|corotational] [tet10] [tip] [refactorise | border K] [event_travel=D] [--out reports]`
use xfem_cut::blade::{run_dynamic, CutItem, CutSet};
use xfem_cut::cut::FrontMode;
use xfem_cut::dynamics::{DynamicOptions, EventSolve, DEFAULT_EVENT_SOLVE, DEFAULT_LAGGED};
use xfem_cut::model::Formulation;
use xfem_cut::study::fixtures::{beam_mesh, seed_beam, seed_blade};
use xfem_cut::study::sweep;

/// The allocator the `xfem-cut` binary and the benches run with (see
/// `src/main.rs`), so that what this times is what a run pays.
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
    let formulation = if args.iter().any(|a| a == "corotational") {
        Formulation::Corotational
    } else {
        Formulation::Linear
    };
    let tet10 = args.iter().any(|a| a == "tet10");
    let event_solve = if args.iter().any(|a| a == "refactorise") {
        EventSolve::Refactorise
    } else if let Some(k) = args
        .iter()
        .position(|a| a == "border")
        .and_then(|k| args.get(k + 1))
        .and_then(|k| k.parse().ok())
    {
        EventSolve::Bordered { max_border: k }
    } else {
        DEFAULT_EVENT_SOLVE
    };
    let out = args
        .iter()
        .position(|a| a == "--out")
        .and_then(|k| args.get(k + 1))
        .map(std::path::PathBuf::from);
    let mesh = beam_mesh(div, tet10);
    let tip = args.iter().any(|a| a == "tip");
    let mut cuts = if tip {
        CutSet {
            front: FrontMode::Tip,
            ..seed_blade(0.1, 0.6)
        }
    } else {
        seed_blade(0.1, 0.6)
    };
    let event_travel: Option<f64> = args
        .iter()
        .find_map(|a| a.strip_prefix("event_travel="))
        .map(|d| d.parse().expect("event_travel=D, D in m"));
    for item in &mut cuts.items {
        if let CutItem::Blade(b) = item {
            b.event_travel = event_travel;
        }
    }
    let build = |cut| seed_beam(mesh.clone(), formulation, cut);
    // The step a case file without `linear_solver` runs: modified Newton
    // on a lagged factor (a linear scene solves once on its factor).
    let opts = DynamicOptions {
        dt: 0.01,
        steps: 70,
        event_solve,
        linear_solver: DEFAULT_LAGGED,
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
    let p = sweep::phases(&rows, 0.1, 0.6);
    eprintln!(
        "phases: uncut step {:.4} ms | sweep step with its events {:.4} ms ({:.2}x) | event {:.4} ms ({:.2}x the uncut step), with the step after {:.4} ms | step after the sweep {:.4} ms ({:.2}x)",
        p.uncut_step * 1e3,
        p.sweep_step * 1e3,
        p.sweep_step / p.uncut_step,
        p.event * 1e3,
        p.event / p.uncut_step,
        p.event_and_step * 1e3,
        p.after_step * 1e3,
        p.after_step / p.uncut_step
    );
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    let step = median(
        rows.iter()
            .filter(|r| !r.event)
            .map(|r| r.step_seconds)
            .collect(),
    );
    // An event with the step after it (its numeric factorisation or border set-up).
    let event = median(
        rows.windows(2)
            .filter(|w| w[0].event)
            .map(|w| w[0].event_seconds + w[1].step_seconds)
            .collect(),
    );
    eprintln!(
        "{event_solve:?}: median step {:.4} ms, median event + step after {:.4} ms ({:.1}x)",
        step * 1e3,
        event * 1e3,
        event / step
    );
    for e in &run.sweep.events {
        eprintln!(
            "  event after step {} (t = {:.2}): DOFs {} → {}, {} elements integrated again, {:.3e} s (model {:.3e}, symbolic {:.3e}), then {}",
            e.step, e.time, e.dofs_before, e.dofs_after, e.changed_elements, e.seconds, e.model_seconds, e.symbolic_seconds,
            e.border.map_or(
                if e.lagged { "on the lagged factor" } else { "refactorised" }.to_string(),
                |k| format!("bordered (k = {k})"),
            )
        );
    }
    if let Some(dir) = out {
        std::fs::create_dir_all(dir.join("data")).unwrap();
        let stem = format!(
            "sweep_series{}{}{}{}",
            if tip { "_tip" } else { "" },
            if formulation == Formulation::Corotational {
                "_corotational"
            } else {
                ""
            },
            if tet10 { "_tet10" } else { "" },
            event_travel.map_or(String::new(), |d| format!("_event_travel_{d}"))
        );
        sweep::write_csv(&dir.join(format!("data/{stem}.csv")), &rows).unwrap();
        let title = format!(
            "Sweep cost: {} {kind} {formulation:?}, {} front, blade during [0.1, 0.6] s",
            mesh.n_elements(),
            if tip { "tip" } else { "extended" }
        );
        sweep::plot(&dir.join(format!("{stem}.svg")), &title, &rows).unwrap();
    }
}
