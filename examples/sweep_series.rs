//! The cost of a sweep as a time series: a blade opens the seed's cut during
//! [0.1, 0.6] s on the beam; prints CSV `time,step_seconds,event_seconds`
//! (event_seconds > 0 where a cut event followed the step) and the sweep's
//! summary on stderr.
//! `cargo run --release --example sweep_series -- NX NY NZ [linear|corotational]`
use xfem_cut::blade::run_dynamic;
use xfem_cut::dynamics::DynamicOptions;
use xfem_cut::model::Formulation;
use xfem_cut::study::fixtures::{beam_mesh, seed_beam, seed_blade};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let div: Vec<usize> = args.iter().take(3).map(|a| a.parse().unwrap()).collect();
    let div = if div.len() == 3 {
        [div[0], div[1], div[2]]
    } else {
        [3, 6, 10]
    };
    let formulation = match args.get(3).map(String::as_str) {
        Some("corotational") => Formulation::Corotational,
        _ => Formulation::Linear,
    };
    let mesh = beam_mesh(div, false);
    let cuts = seed_blade(0.1, 0.6);
    let build = |cut| seed_beam(mesh.clone(), formulation, cut);
    let opts = DynamicOptions {
        dt: 0.01,
        steps: 70,
        ..DynamicOptions::default()
    };
    let run = run_dynamic(&cuts, &mesh, &build, opts, |_, _, _| {}).unwrap();
    println!("time,step_seconds,event_seconds");
    let mut events = run.sweep.events.iter().peekable();
    for (k, &(t, dt, _)) in run.sweep.series.iter().enumerate() {
        let mut ev = 0.0;
        while let Some(e) = events.next_if(|e| e.step == k + 1) {
            ev += e.seconds;
        }
        println!("{t:.4},{dt:.6e},{ev:.6e}");
    }
    eprintln!("{} tets: {}", mesh.n_elements(), run.sweep);
}
