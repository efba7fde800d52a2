//! Where a cut event's projection changes the strain energy: a dynamic
//! blade scene run to the step before the event at `TIME`, the models at
//! the cut before and after, and per element the strain energy of the old
//! field and of the mapped one (each on its model's field points); the
//! elements that change most, with what they are in both models.
//!
//! `cargo run --release --example event_misfit -- case.toml TIME PREVIOUS_EVENT_TIME`
use nalgebra::Matrix3;
use std::path::Path;
use xfem_cut::blade::{map_state, run_dynamic, CutSet};
use xfem_cut::cut::ElementCut;
use xfem_cut::model::Model;
use xfem_cut::scene::{Analysis, Scene};

fn energies(model: &Model, d: &[f64]) -> Vec<f64> {
    let (lambda, mu) = (model.lame.lambda, model.lame.mu);
    (0..model.mesh.n_elements())
        .map(|e| {
            model
                .field_points(e)
                .into_iter()
                .map(|(x, w, side)| {
                    let (_, g) = model.field_at(d, e, &x, side);
                    let eps: Matrix3<f64> = (g + g.transpose()) * 0.5;
                    let tr = eps.trace();
                    w * 0.5 * (lambda * tr * tr + 2.0 * mu * eps.component_mul(&eps).sum())
                })
                .sum()
        })
        .collect()
}

fn describe(model: &Model, e: usize) -> String {
    let Some(c) = &model.cut else {
        return "uncut".into();
    };
    let conn = model.mesh.element(e);
    let kind = match &c.elements[e] {
        ElementCut::Uncut => "uncut".to_string(),
        ElementCut::Touched { side } => format!("touched{side:+}"),
        ElementCut::Cut { sub_tets, partial } => {
            format!(
                "cut({} sub-tets{})",
                sub_tets.len(),
                if *partial { ", partial" } else { "" }
            )
        }
    };
    let tips = conn
        .iter()
        .filter(|&&i| c.tip.get(i).copied().flatten().is_some())
        .count();
    let heav = conn.iter().filter(|&&i| c.enriched[i].is_some()).count();
    let phis: Vec<String> = conn
        .iter()
        .take(4)
        .map(|&i| format!("{:.1e}", c.phi[i]))
        .collect();
    format!(
        "{kind} tip nodes {tips} heaviside {heav} phi [{}]",
        phis.join(" ")
    )
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = &args[0];
    let t_event: f64 = args[1].parse().unwrap();
    let t_prev: f64 = args[2].parse().unwrap();
    let text = std::fs::read_to_string(path).unwrap();
    let scene = Scene::parse(&text, Path::new(path)).unwrap();
    let mesh = scene.mesh(0).unwrap();
    let Analysis::Dynamic { options, .. } = scene.analysis else {
        panic!("not a dynamic scene")
    };
    let cuts = CutSet::from_scene(&scene).unwrap();
    let (fixed, tractions) = scene.selections(&mesh).unwrap();
    let build = |cut| scene.model_input(mesh.clone(), cut, fixed.clone(), &tractions);
    let mut state = None;
    let opts = xfem_cut::dynamics::DynamicOptions {
        steps: (t_event / options.dt).round() as usize,
        ..options
    };
    run_dynamic(&cuts, &mesh, &build, opts, |_, _, nm| {
        if (nm.state.time - t_event).abs() < 1e-9 {
            state = Some(nm.state.clone());
        }
    })
    .unwrap();
    let state = state.expect("a step at TIME");
    let old = build(cuts.setup_at(&mesh, t_prev).unwrap()).unwrap();
    let new = build(cuts.setup_at(&mesh, t_event).unwrap()).unwrap();
    let mapped = map_state(&old, &new, &state);
    let (eo, en) = (energies(&old, &state.d), energies(&new, &mapped.d));
    let (so, sn): (f64, f64) = (eo.iter().sum(), en.iter().sum());
    println!("strain energy old {so:.4e} new {sn:.4e}");
    let mut order: Vec<usize> = (0..eo.len()).collect();
    order.sort_by(|&a, &b| (en[b] - eo[b]).abs().total_cmp(&(en[a] - eo[a]).abs()));
    for &e in order.iter().take(12) {
        println!(
            "element {e}: {:.3e} -> {:.3e}\n   old: {}\n   new: {}",
            eo[e],
            en[e],
            describe(&old, e),
            describe(&new, e)
        );
    }
}
