//! A dynamic scene with blades, level 0: per cut event its time, DOFs,
//! elements integrated again, kinetic and strain energy before and after
//! (same displacement and velocity, the projected ones where DOFs change
//! meaning), the relative change, and what the projection fitted.
//!
//! `cargo run --release --example event_energies -- cases/cut_progressive.toml`
use std::path::Path;
use xfem_cut::blade::{run_dynamic, CutSet};
use xfem_cut::scene::{Analysis, Scene};

fn main() {
    let path = std::env::args().nth(1).expect("case");
    let text = std::fs::read_to_string(&path).unwrap();
    let scene = Scene::parse(&text, Path::new(&path)).unwrap();
    let mesh = scene.mesh(0).unwrap();
    let Analysis::Dynamic { options, .. } = scene.analysis else {
        panic!("not a dynamic scene")
    };
    let cuts = CutSet::from_scene(&scene).unwrap();
    let (fixed, tractions) = scene.selections(&mesh).unwrap();
    let build = |cut| scene.model_input(mesh.clone(), cut, fixed.clone(), &tractions);
    let run = run_dynamic(&cuts, &mesh, &build, options, |_, _, _| {}).unwrap();
    println!("time,dofs_before,dofs_after,changed,kinetic_before,strain_before,kinetic_after,strain_after,change,fitted,conditioning");
    for (e, p) in run.sweep.events.iter().zip(&run.sweep.projections) {
        println!(
            "{:.4},{},{},{},{:.4e},{:.4e},{:.4e},{:.4e},{:.2e},{},{:.1e}",
            e.time,
            e.dofs_before,
            e.dofs_after,
            e.changed_elements,
            e.before.kinetic,
            e.before.strain,
            e.after.kinetic,
            e.after.strain,
            e.energy_jump(),
            p.as_ref().map_or(0, |p| p.fitted),
            p.as_ref().map_or(f64::NAN, |p| p.conditioning),
        );
    }
}
