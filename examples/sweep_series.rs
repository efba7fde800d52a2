//! The cost of a sweep as a time series: a blade opens the seed's cut during
//! [0.1, 0.6] s on the beam; prints CSV `time,step_seconds,event_seconds`
//! (event_seconds > 0 where a cut event followed the step) and the sweep's
//! summary on stderr.
//! `cargo run --release --example sweep_series -- NX NY NZ [linear|corotational]`
use nalgebra::{Point3, Vector3};
use xfem_cut::blade::{run_dynamic, Blade, CutItem, CutSet};
use xfem_cut::cut::DEFAULT_SNAP;
use xfem_cut::dynamics::DynamicOptions;
use xfem_cut::material::Material;
use xfem_cut::mesh::box_mesh;
use xfem_cut::model::{Formulation, Model, ModelInput};

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
    let mesh = box_mesh(Point3::origin(), Point3::new(0.03, 0.06, 0.2), div);
    let blade = Blade::straight(
        0,
        Point3::new(0.0, -0.01, 0.1),
        Point3::new(0.0, 0.07, 0.1),
        Vector3::new(0.015, 0.0, 0.0),
        0.1,
        0.6,
    )
    .unwrap();
    let cuts = CutSet {
        items: vec![CutItem::Blade(blade)],
        snap: DEFAULT_SNAP,
        front: xfem_cut::cut::FrontMode::Extend,
    };
    let build = |cut| {
        let fixed = mesh
            .nodes
            .iter()
            .enumerate()
            .filter(|(_, p)| p.z == 0.0)
            .map(|(i, _)| (i, [Some(0.0); 3]))
            .collect();
        Model::build(ModelInput {
            mesh: mesh.clone(),
            material: Material {
                young: 3.0e5,
                poisson: 0.35,
                density: 1070.0,
            },
            formulation,
            cut,
            fixed,
            gravity: Some(Vector3::new(9.81, 0.0, 0.0)),
            body_force: None,
            tractions: &[],
            need_mass: true,
        })
    };
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
